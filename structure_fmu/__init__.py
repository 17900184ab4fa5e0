"""Structure unit: the 18-DoF ANCF multibody solver (Otsuka et al. 2019, Secs. II-IV), the shear-deformable ANCF
element (Peng et al. 2019, Eqs. 1-10), the strain-based beam with joint parameters (Otsuka et al. 2022, Secs. 2-3),
and its FMI 2.0 slave.

  solver.py          StructureSolver, the API of docs/solver_api.md (spec, parameters, inputs Q, state, outputs)
  interface.py       the unit's FMI interface, declared once: blocks, monitors, sensors, parameters
  structure_slave.py the FMI slave over StructureSolver, registering and publishing that interface
  topology.py        StructureTopology: the shared topology (fmu_common) plus joints, sections, motions, masses,
                     loads, and the map E = T q + P p(t) to reduced coordinates
  section.py         beam cross-section properties from a plate or explicit stiffnesses
  element.py         the ANCF element: mass matrix, elastic energy, force and Jacobian (Eqs. 5, 7-11)
  element_kernels.c  the elastic force and tangent in C (compiled and loaded by fmu_common.c_library)
  shear_element.py   the shear-deformable element (Peng et al. 2019): the chord plane's continuum with the Green
                     strain, plus the flap bending and torsion of element.py; energy, force and Jacobian
  shear_element_kernels.c  its continuum's force and tangent in C (compiled and loaded by fmu_common.c_library)
  iteration_lu.py    the LU of generalized-alpha's iteration matrix, banded where its sparsity allows
  fidelities.py      the registry of the structural fidelities (their model classes) and the model contract
                     StructuralModel the integrators call
  model.py           mass, forces, constraints and energy of the assembled ANCF structure (Eq. 4), either element
  slots.py           the exchanged coordinates as combinations of free vectors, free scalars along fixed
                     directions and prescribed vectors; shared slots
  pins.py            pins at any node (shared points, rows closing a loop of rigid bodies) and sliders (a fixed
                     line's travel as a coordinate; rows on another body)
  constraints.py     the nonlinear internal constraints (Eqs. 6, 17), linear rows and the joints' axis rows
  joint_rows.py      a slider's rows on the frame of another body's node
  joints.py          revolute joints: fold angle, spring actuator, latch
  joint_monitors.py  per-joint constraint monitors (point mismatch, axis products) on E
  strain_kinematics.py  the strain-based recursion: nodal vectors from strains and joint parameters, derivatives
  strain_kernels.c   the strain-based sweeps along a body in C (compiled and loaded by fmu_common.c_library)
  strain_model.py    the strain-based model (Otsuka et al. 2022, Eq. 9) over the ANCF model's inertia and forces
  motion.py          prescribed rigid motions: clamps, driven roots (Eq. 27), heave/pitch laws
  damping.py         damping of deformation
  integrators.py     RK4 and generalized-alpha with projection on the constraints; their registry and contract
                     (Integrator)
  modes.py           natural frequencies and modes linearized at rest
  sensors.py         probes and strain gauges

Shared with the aero unit, in fmu_common: the typed specs of the scene, errors, the FMI slave plumbing, the
topology, the shape functions.
"""
