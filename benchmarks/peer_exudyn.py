"""Peer cases against Exudyn (the `peers` extra): the spin-up beam and the rotating falling beam, each run by the
structure solver (structure_fmu.solver.StructureSolver) and by Exudyn from the same scene data.

- Spin-up (scenes/spin_up.toml; Otsuka et al. 2019, Sec. VI.B, driven by Eq. 27): Exudyn's planar ANCF cable
  (ObjectANCFCable2D), the headline row (the spin-up is planar: the planar cable is the fair peer) and, as a second
  row, its 3D cable (ObjectANCFCable). The driven root is a clamp: root
  position fixed and root slope prescribed as R(theta(t)) e_x by coordinate constraints, theta from
  structure_fmu.motion.SpinUp. Values: the tip's in-plane deflection (m, its distance from the rigidly rotating
  beam line, positive when it lags), sampled every coupling step, and its peak |deflection| (m).
- Rotating falling beam (scenes/rotating_beam.toml; Otsuka et al. 2019, Sec. VI.C): Exudyn's geometrically exact
  beam (ObjectBeamGeometricallyExact, rotation-vector Lie-group nodes), root held by a revolute joint about Z,
  initial rigid rotation and gravity from the scene. Values: the tip's position (m) every coupling step.

Both codes take the scene's step with generalized-alpha at the scene's rho_inf and fixed steps (Exudyn's adaptive
step is off, so a Newton failure stops the run instead of changing the step). wingsim runs as `wingsim run` runs it:
`run_scene` through the FMUs (built beforehand, not timed), the units reading what the scene's `record` table asks
for, here the tip probe's position alone (RECORD), as Exudyn's sensor records; its timed part is run_scene after its
units are loaded and initialized (the communication steps, their exchanges and records, and the end of the run),
Exudyn's its SolveDynamic after its Assemble; whole processes (benchmarks/peers.py) count the rest. Exudyn is tuned:
the prescribed root angle is a symbolic user function (exudyn.symbolic), which Exudyn evaluates in C++ instead of
calling back into Python at every evaluation, and its Newton iteration stops at a relative residual of
NEWTON_RELATIVE_TOLERANCE or an absolute one of NEWTON_ABSOLUTE_TOLERANCE (with its default absolute tolerance
1e-10, or 1e-8, it does not converge at these stiffnesses: fixed steps stop and adaptive ones are cut). Against
tolerances 100 times tighter (1e-8, 1e-6) these move its spin-up deflection by 1.6e-7 m (its error against the
reference is 4.3e-6 m, 0-5 s) and its rotating beam's tip by 2.8e-7 m (0-0.2 s): its accuracy is kept. The
references are the structure solver refined in space and time (REFINED): the spin-up's error is the time step's
(docs/structure.md: 9 and 18 elements differ by 1.7e-6 m), the rotating beam's mostly the elements'; Exudyn refined
the same way approaches the same values.

Differences that remain: Exudyn's cables carry no torsion and no chord gradient (the motions are planar and
torsion-free; ours carries both); its geometrically exact beam is shear-deformable (shear stiffness 5/6 G A with
nu = 0.3, a relative shear flexibility of order (h / L)^2) and needs a rotary inertia about the chord, taken as
the plate's rho c h^3 / 12 where the scene's is 0 (ours then has none).
"""
from __future__ import annotations

import functools

import numpy as np
from peer_case import Measurement, PeerCase, Timer
from report import ROOT

from structure_fmu.topology import StructureTopology
from fmu_common.specs import StructureUnitSpec
from fmu_common.wing_spec import StructureSpec

SPIN_UP = ROOT / "scenes" / "spin_up.toml"
ROTATING_BEAM = ROOT / "scenes" / "rotating_beam.toml"
NEWTON_RELATIVE_TOLERANCE = 1e-6
NEWTON_ABSOLUTE_TOLERANCE = 1e-4
RECORD = ["record.probes=position", "record.monitors=constraints"]
TIP_PROBE = "tip"
POISSON_RATIO = 0.3      # the rotating beam's plate (scenes/rotating_beam.toml), for Exudyn's shear stiffness
SHEAR_CORRECTION = 5 / 6
REFINED = {"spin_up": ["structure.elements_per_body=18", "structure.step=0.001"],
           "rotating_beam": ["structure.elements_per_body=30", "structure.step=1e-4"]}
QUICK_STOP = {"spin_up": 5.0, "rotating_beam": 0.2}


# ------------------------------------------------------------------------------------------------ scene data
def _scene(path, stop, overrides=()):
    from orchestrator.scene.load import load_scene
    return load_scene(path, [*([f"time.stop={stop!r}"] if stop is not None else []), *overrides])


def _sample_times(scene):
    """The coupling instants (s) after t = 0 up to time.stop: where both sides record their values."""
    dt, stop = scene["coupling"]["step"], scene["time"]["stop"]
    return dt * np.arange(1, int(round(stop / dt)) + 1)


def _spin_law(scene):
    from structure_fmu.motion import SpinUp
    joint = scene["structure"]["joints"][0]
    return SpinUp([0.0, 1.0, 0.0], [0.0, 0.0, 0.0], joint["omega"], joint["ramp_time"])


def _body(scene):
    """(StructureBody, Section) of the scene's single body."""
    body = next(iter(StructureTopology.from_spec(StructureSpec.from_scene(scene)).bodies.values()))
    return body, body.section


def _deflection(law, t, x, z):
    """Tip distance (m) from the rigid line rotated about Y by theta(t): tip . R_y(theta) e_z (positive lagging)."""
    theta = np.array([law.angle(ti)[0] for ti in t])
    return x * np.sin(theta) + z * np.cos(theta)


# ------------------------------------------------------------------------------------------------ wingsim
FMU_FOLDER = "WINGSIM_PEERS_FMUS"
"""Environment variable naming the folder the FMUs of the cases are built in, one subfolder per scene digest,
shared with the processes benchmarks/peers.py starts; unset: a temporary folder of this process."""
_TEMPORARY = []


def fmus_of(scene):
    """The folder holding the FMUs of `scene` (under FMU_FOLDER), built unless up to date there (not timed)."""
    import os
    import tempfile
    from pathlib import Path

    from orchestrator.build.fmus import build_digest, build_fmus, fmus_up_to_date
    if not os.environ.get(FMU_FOLDER) and not _TEMPORARY:
        _TEMPORARY.append(tempfile.TemporaryDirectory(prefix="wingsim_peers_"))
    folder = Path(os.environ.get(FMU_FOLDER) or _TEMPORARY[0].name, build_digest(scene)[:16])
    if not fmus_up_to_date(scene, folder):
        build_fmus(scene, folder)
    return folder


def _run_tip(scene):
    """The scene through `wingsim run`'s path (module docstring), timed from the moment its units are loaded and
    initialized (as Exudyn's SolveDynamic after its Assemble) to the end of the run: (Measurement without values,
    the coupling instants after t = 0, the tip probe's positions there (n, 3))."""
    import time
    from types import SimpleNamespace

    from orchestrator.run import units
    from orchestrator.run.master import run_scene
    folder, loaded = fmus_of(scene), []

    def make_unit(**kwargs):
        unit = units.make_unit(**kwargs)
        loaded.append((time.perf_counter(), time.process_time()))
        return unit

    result = run_scene(scene, backend="fmu", fmu_dir=folder,
                       units=SimpleNamespace(make_unit=make_unit, UnitError=units.UnitError))
    wall, cpu = time.perf_counter() - loaded[-1][0], time.process_time() - loaded[-1][1]
    if result.status != "ok":
        raise RuntimeError(f"wingsim did not finish {scene['name']}: {result.status}: {result.message}")
    series, times = result.series, _sample_times(scene)
    if not np.allclose(series.time[1:], times, atol=1e-9):
        raise RuntimeError(f"wingsim recorded at {series.time[1:4]}..., not every {scene['coupling']['step']} s")
    return Measurement(wall, cpu), times, series.positions[1:, series.probe_names.index(TIP_PROBE)]


def _solver_tip(scene):
    """The tip's position at the coupling instants from the structure solver API (the refined references)."""
    from structure_fmu.solver import StructureSolver
    body, _ = _body(scene)
    topology = StructureTopology.from_spec(StructureSpec.from_scene(scene))
    tip = topology.point_rows(body.name, body.length, body.axis_position)[0]
    solver = StructureSolver(StructureUnitSpec.from_scene(scene))
    times, out = _sample_times(scene), []
    with Timer() as timer:
        for t in times:
            solver.advance(t)
            out.append(tip @ solver.e.reshape(-1, 3))
    return Measurement(timer.wall_s, timer.cpu_s), times, np.array(out)


def _ours_spin_up(scene, run=_run_tip):
    measurement, t, tip = run(scene)
    deflection = _deflection(_spin_law(scene), t, tip[:, 0], tip[:, 2])
    measurement.values = {"t": t, "deflection": deflection, "peak": float(np.abs(deflection).max())}
    return measurement


def _ours_rotating(scene, run=_run_tip):
    measurement, t, tip = run(scene)
    measurement.values = {"t": t, "tip": tip}
    return measurement


# ------------------------------------------------------------------------------------------------ Exudyn
def _exudyn_settings(exu, scene):
    structure = scene["structure"]
    stop, h = scene["time"]["stop"], structure["step"]
    settings = exu.SimulationSettings()
    settings.timeIntegration.endTime = stop
    settings.timeIntegration.numberOfSteps = int(round(stop / h))
    settings.timeIntegration.generalizedAlpha.spectralRadius = structure["rho_inf"]
    settings.timeIntegration.newton.relativeTolerance = NEWTON_RELATIVE_TOLERANCE
    settings.timeIntegration.newton.absoluteTolerance = NEWTON_ABSOLUTE_TOLERANCE
    settings.timeIntegration.adaptiveStep = False
    settings.timeIntegration.verboseMode = 0
    settings.solution.file.write = False
    settings.solution.sensors.writePeriod = scene["coupling"]["step"]
    settings.show.computationTime = False
    settings.show.statistics = False
    return settings


def _exudyn_solve(exu, mbs, scene, sensor):
    """Timed SolveDynamic; the sensor's positions (n, 3) at the coupling instants after t = 0."""
    mbs.Assemble()
    settings = _exudyn_settings(exu, scene)
    with Timer() as timer:
        ok = mbs.SolveDynamic(settings)
    if not ok:
        raise RuntimeError(f"Exudyn {exu.__version__} did not finish {scene['name']} (fixed steps)")
    data = mbs.GetSensorStoredData(sensor)
    times = _sample_times(scene)
    rows = data[1:]                                  # the first row is t = 0
    if len(rows) != len(times) or not np.allclose(rows[:, 0], times, atol=1e-9):
        raise RuntimeError(f"Exudyn's sensor was written at {rows[:3, 0]}..., not every {scene['coupling']['step']} s")
    return Measurement(timer.wall_s, timer.cpu_s), times, rows[:, 1:4]


def _symbolic_spin_up(esym, law):
    """theta(t) and dtheta/dt(t) of the spin-up law (structure_fmu.motion.SpinUp.angle, Otsuka et al. 2019,
    Eq. 27) as functions of a symbolic time, building Exudyn symbolic expressions."""
    ws, Ts = law.omega, law.ramp_time
    c = 2 * np.pi / Ts

    def theta(t):
        return esym.IfThenElse(t < Ts, ws / Ts * (t**2 / 2 + (esym.cos(c * t) - 1) / c**2), ws * (t - Ts / 2))

    def omega(t):
        return esym.IfThenElse(t < Ts, ws / Ts * (t - esym.sin(c * t) / c), esym.Real(ws))

    return theta, omega


def _exudyn_spin_up(scene, planar):
    """The spin-up with n ANCF cables (3D, or planar in the x-y plane, which stands for x-z: the deflection is
    computed with y -> -z so that both measure the same lag)."""
    import exudyn as exu
    from exudyn.advancedUtilities import CreateSymbolicUserFunction
    from exudyn.itemInterface import (MarkerNodeCoordinate, NodePoint2DSlope1, NodePointGround, NodePointSlope1,
                                      ObjectANCFCable, ObjectANCFCable2D, ObjectConnectorCoordinate, SensorNode)
    body, section = _body(scene)
    law, n = _spin_law(scene), len(body.elements)
    le = body.length / n
    mbs = exu.SystemContainer().AddSystem()
    Node, Cable = (NodePoint2DSlope1, ObjectANCFCable2D) if planar else (NodePointSlope1, ObjectANCFCable)
    reference = (lambda x: [x, 0.0, 1.0, 0.0]) if planar else (lambda x: [x, 0.0, 0.0, 1.0, 0.0, 0.0])
    nodes = [mbs.AddNode(Node(referenceCoordinates=reference(i * le))) for i in range(n + 1)]
    for a, b in zip(nodes[:-1], nodes[1:]):
        mbs.AddObject(Cable(nodeNumbers=[a, b], length=le, massPerLength=section.mass_per_length,
                            bendingStiffness=section.flap, axialStiffness=section.axial))
    ground = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=mbs.AddNode(NodePointGround()), coordinate=0))

    # root slope R(theta) e_x as displacements from the reference slope e_x (the constraint acts on coordinates
    # without their reference values): 3D (cos - 1, 0, -sin) about Y; planar (cos - 1, sin) about Z; each offset
    # and its rate a symbolic user function of its own, evaluated by Exudyn in C++ (kept alive in `symbolic`)
    esym, sign = exu.symbolic, 1.0 if planar else -1.0
    theta, omega = _symbolic_spin_up(esym, law)

    def cos_minus_one(mbs, t, itemNumber, lOffset):
        return esym.cos(theta(t)) - 1.0

    def cos_minus_one_t(mbs, t, itemNumber, lOffset):
        return -esym.sin(theta(t)) * omega(t)

    def sine(mbs, t, itemNumber, lOffset):
        return sign * esym.sin(theta(t))

    def sine_t(mbs, t, itemNumber, lOffset):
        return sign * esym.cos(theta(t)) * omega(t)

    driven = ({2: (cos_minus_one, cos_minus_one_t), 3: (sine, sine_t)} if planar else
              {3: (cos_minus_one, cos_minus_one_t), 5: (sine, sine_t)})
    symbolic = []
    for k in range(4 if planar else 6):
        marker = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=nodes[0], coordinate=k))
        functions = driven.get(k)
        if functions is None:
            mbs.AddObject(ObjectConnectorCoordinate(markerNumbers=[ground, marker]))
        else:
            offset, rate = (CreateSymbolicUserFunction(mbs, f, name, itemTypeName="ObjectConnectorCoordinate")
                            for f, name in zip(functions, ("offsetUserFunction", "offsetUserFunction_t")))
            symbolic += [offset, rate]
            mbs.AddObject(ObjectConnectorCoordinate(markerNumbers=[ground, marker], offsetUserFunction=offset,
                                                    offsetUserFunction_t=rate))
    sensor = mbs.AddSensor(SensorNode(nodeNumber=nodes[-1], storeInternal=True,
                                      outputVariableType=exu.OutputVariableType.Position))
    measurement, t, tip = _exudyn_solve(exu, mbs, scene, sensor)
    deflection = _deflection(law, t, tip[:, 0], -tip[:, 1] if planar else tip[:, 2])
    measurement.values = {"t": t, "deflection": deflection, "peak": float(np.abs(deflection).max())}
    return measurement


def _exudyn_rotating(scene):
    """The rotating beam with n geometrically exact elements on rotation-vector Lie-group nodes."""
    import exudyn as exu
    from exudyn.itemInterface import (LoadMassProportional, MarkerBodyMass, MarkerBodyRigid, MarkerNodeRigid,
                                      NodeRigidBodyRotVecLG, ObjectBeamGeometricallyExact, ObjectGround,
                                      ObjectJointGeneric, SensorNode)
    body, section = _body(scene)
    spec = scene["structure"]["bodies"][0]
    if spec["span_axis"] != [1.0, 0.0, 0.0] or spec["chord_axis"] != [0.0, 1.0, 0.0]:
        raise ValueError("the Exudyn model of the rotating beam expects span along X and chord along Y")
    n, omega = len(body.elements), np.asarray(spec["angular_velocity"], float)
    le, mu, c, h = body.length / n, section.mass_per_length, section.chord, section.thickness
    rho_I_yy = section.rotary_inertia or mu * h**2 / 12   # Exudyn's rotation about the chord needs an inertia
    youngs = section.axial / (c * h)
    shear = SHEAR_CORRECTION * youngs / (2 * (1 + POISSON_RATIO)) * c * h
    data = exu.BeamSection()
    data.massPerLength = mu
    data.inertia = np.diag([section.chord_inertia + rho_I_yy, rho_I_yy, section.chord_inertia])
    data.stiffnessMatrix = np.diag([section.axial, shear, shear, section.torsion, section.flap, section.chordwise])
    mbs = exu.SystemContainer().AddSystem()
    nodes = []
    for i in range(n + 1):
        x = np.array([i * le, 0.0, 0.0])
        nodes.append(mbs.AddNode(NodeRigidBodyRotVecLG(referenceCoordinates=[*x, 0.0, 0.0, 0.0],
                                                       initialVelocities=[*np.cross(omega, x), *omega])))
    gravity = list(scene["structure"]["gravity"])
    for a, b in zip(nodes[:-1], nodes[1:]):
        element = mbs.AddObject(ObjectBeamGeometricallyExact(nodeNumbers=[a, b], length=le, sectionData=data))
        mbs.AddLoad(LoadMassProportional(markerNumber=mbs.AddMarker(MarkerBodyMass(bodyNumber=element)),
                                         loadVector=gravity))
    ground = mbs.AddMarker(MarkerBodyRigid(bodyNumber=mbs.AddObject(ObjectGround()), localPosition=[0.0, 0.0, 0.0]))
    root = mbs.AddMarker(MarkerNodeRigid(nodeNumber=nodes[0]))
    mbs.AddObject(ObjectJointGeneric(markerNumbers=[ground, root], constrainedAxes=[1, 1, 1, 1, 1, 0]))
    sensor = mbs.AddSensor(SensorNode(nodeNumber=nodes[-1], storeInternal=True,
                                      outputVariableType=exu.OutputVariableType.Position))
    measurement, t, tip = _exudyn_solve(exu, mbs, scene, sensor)
    measurement.values = {"t": t, "tip": tip}
    return measurement


# ------------------------------------------------------------------------------------------------ accuracy
def _spin_up_errors(values, reference):
    """Largest deflection difference over the history and the difference of the peaks (m)."""
    return {"deflection, largest error (m)": float(np.abs(values["deflection"] - reference["deflection"]).max()),
            "peak error (m)": abs(values["peak"] - reference["peak"])}


def _tip_errors(values, reference):
    """Largest and final distance (m) between the tip positions."""
    distance = np.linalg.norm(values["tip"] - reference["tip"], axis=1)
    return {"tip, largest error (m)": float(distance.max()), "tip error at the end (m)": float(distance[-1])}


def _exudyn_version():
    """The peer's label, read without importing it (a missing package fails when a case runs, by its import)."""
    from importlib.metadata import PackageNotFoundError, version
    try:
        return f"Exudyn {version('exudyn')}"
    except PackageNotFoundError:
        return "Exudyn (not installed: pip install -e '.[peers]')"


def cases(quick=False) -> list[PeerCase]:
    """The peer cases, the planar spin-up first (the headline row); `quick` shortens the simulated time (spin-up
    to 5 s, rotating beam to 0.2 s)."""
    spin_stop, rotating_stop = (QUICK_STOP["spin_up"], QUICK_STOP["rotating_beam"]) if quick else (None, None)
    spin_up = lambda *overrides: _scene(SPIN_UP, spin_stop, overrides)            # noqa: E731
    rotating = lambda *overrides: _scene(ROTATING_BEAM, rotating_stop, overrides)  # noqa: E731
    peer = _exudyn_version()
    same = (f"scene's step and elements, generalized-alpha with its rho_inf on both sides, fixed steps; wingsim "
            f"through its FMUs recording the tip's position ({' '.join(RECORD)}); Exudyn's Newton tolerances "
            f"{NEWTON_RELATIVE_TOLERANCE:g} relative, {NEWTON_ABSOLUTE_TOLERANCE:g} absolute")
    spin_name = (f"spin-up beam (Simo and Vu-Quoc), 0-{spin_stop or 20:g} s, 9 elements, generalized-alpha 5 ms")
    spin_reference = functools.cache(lambda: _ours_spin_up(spin_up(*REFINED["spin_up"]), run=_solver_tip).values)
    driven = "root clamp rotated by Otsuka et al. 2019, Eq. 27 through coordinate constraints (symbolic user functions)"
    return [
        PeerCase(name=spin_name, peer=f"{peer}, planar ANCF cables (ObjectANCFCable2D)",
                 what=f"{same}; {driven}; the planar element has 4 coordinates per node against our 9; reference: "
                      f"ours, 18 elements, 1 ms",
                 ours=lambda: _ours_spin_up(spin_up(*RECORD)), peer_run=lambda: _exudyn_spin_up(spin_up(), planar=True),
                 reference=spin_reference, errors=_spin_up_errors, target=1.0),
        PeerCase(name=spin_name, peer=f"{peer}, 3D ANCF cables (ObjectANCFCable)",
                 what=f"{same}; {driven}; reference: ours, 18 elements, 1 ms",
                 ours=lambda: _ours_spin_up(spin_up(*RECORD)),
                 peer_run=lambda: _exudyn_spin_up(spin_up(), planar=False),
                 reference=spin_reference, errors=_spin_up_errors, target=0.5),
        PeerCase(name=f"rotating falling beam, 15 elements, {rotating_stop or 1:g} s, 0.5 ms",
                 peer=f"{peer}, geometrically exact beam (ObjectBeamGeometricallyExact)",
                 what=f"{same}; revolute root about Z; shear-deformable peer (5/6 G A); reference: ours, 30 elements, "
                      f"0.1 ms",
                 ours=lambda: _ours_rotating(rotating(*RECORD)), peer_run=lambda: _exudyn_rotating(rotating()),
                 reference=lambda: _ours_rotating(rotating(*REFINED["rotating_beam"]), run=_solver_tip).values,
                 errors=_tip_errors, target=0.5),
    ]
