"""Aerodynamic FMI unit (UVLM with flat, prescribed or free wake; strip theory), Otsuka et al. 2019, Sec. V.

  solver.py         AeroSolver, the API of docs/aero_api.md (spec, parameters, inputs, state, outputs)
  models.py         the registry of the aero models (aero.model -> strip theory or a UVLM with its wake model)
                    and their contract AerodynamicModel
  uvlm.py           unsteady vortex-lattice step: no penetration (Eq. 22), Kutta condition, unsteady
                    Bernoulli (Eq. 23), panel forces (Eq. 25); the flat-wake model and its closed form
  wake.py           shed ring wakes: shedding, convection (prescribed / free), truncation
  strip.py          quasi-steady strip theory, the cheapest model
  factorization.py  bound (+ horseshoe) influence matrices and LU, reused while the wing moves rigidly
  rigid.py          rigid-motion test of a point set (Kabsch)
  loads.py          Q (Eq. 12), lift, drag, moments, coefficients
  lattice.py        vortex-ring lattice of each body as fixed shape-function matrices (Eqs. 12, 20, 21, 24)
  biot_savart.py    velocity of straight vortex segments with a Scully core (Eq. 19)
  biot_savart.c     the same in C, pair by pair, and the treecode's walk (compiled and loaded by
                    fmu_common.c_library)
  treecode.py       far field of many segments: Barnes-Hut octree, monopole and dipole, error bound; the free
                    wake's convection
  flat_wake_step.py the flat-wake (uvlm-flat) step in one compiled call on buffers allocated once: lattice,
                    influence matrices, LU, circulation, forces, Q (flat_wake_step.c; the numpy path the reference)
  vlm.py            steady VLM: influence matrix, flat horseshoe wake, pressure forces (Eqs. 22, 23, 25)
  interface.py      the unit's FMI interface, declared once: blocks, loads, parameters
  aero_slave.py     the FMI slave over AeroSolver, registering and publishing that interface

It imports only fmu_common (what both units share: the scene's specs, topology, shape functions, errors, FMI
plumbing, compiled kernels) and its own modules, never the structure unit.
"""
