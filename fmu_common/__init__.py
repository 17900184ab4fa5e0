"""What the structure and aero units share, and nothing else: no structural or aerodynamic physics.

  errors.py           SceneError, InputError, SolverDiverged; unknown-key and input checks
  schema.py           the vocabulary of the scene schema: typed keys, tables, arrays of tables, variants
  scene_schema.py     every scene key declared once, and resolve_scene (docs/scenes.md is generated from it)
  choices.py          the scene's named choices (fidelity, aero model, integrator): names and the traits both
                      units and the master ask of them (elements per body, nodes anywhere, a shed wake, ...)
  scene_bounds.py     the size bounds of a scene and the rough memory estimate of a run
  scissors.py         chains of scissor-like elements: the scene shorthand expanded into bodies, pins, probes
  specs.py            what each unit reads of a resolved scene, as frozen typed specs (StructureUnitSpec,
                      AeroUnitSpec: time, coupling, flow, aero, probes, strain gauges), converted once
  wing_spec.py        the structure table as typed specs: bodies and sections, joints and their actuators,
                      masses, loads, the [load] case, the prescribed motion
  topology.py         the structural topology both units build from a structure spec: bodies, nodes, elements,
                      reference lines, chords, hinges, initial coordinates and the topology hash
  shape_functions.py  the ANCF element's shape functions (Otsuka et al. 2019, Eq. 2), with which the aero
                      unit maps panel points and forces to the exchanged coordinates (Eq. 12)
  vectors.py          3-vector kernels: cross product, rotation about an axis, perpendiculars
  compiled.py         which kernels run (compiled or numpy) and the per-machine cache folder of the C kernels
  c_library.py        C kernels: compiled once per machine (or into an FMU by its build), loaded with ctypes
  interface.py        the vocabulary of a unit's FMI interface table (blocks, outputs, parameters) and its
                      layout into variables with contiguous value references
  fmi_slave.py        the pythonfmu plumbing of both FMI slaves (SolverSlave: layout, refusals, phases, states)
  fmi_state.py        a unit's state as bytes, read back by an unpickler that builds nothing but the state
  fmi_units.py        SI units of FMI variables (UnitReal) and the model description's UnitDefinitions
  threads.py          limit_blas_threads(), called where a process or a unit starts
  dependencies.py     the third-party packages a unit needs, checked (inside an FMU) before it imports them

Both FMUs embed this package beside their own (structure.fmu: structure_fmu; aero.fmu: aero_fmu), the
same version, so that they run in one process.
"""
