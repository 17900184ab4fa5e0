"""Peer cases against PteraSoftware (unsteady ring vortex-lattice method), for benchmarks/peers.py.

The problem both codes solve: a flat rectangular wing, chord c = 1 m, span 8 m (aspect ratio 8), started
impulsively at alpha = 5 deg in a stream of V = 10 m/s, air density 1.2 kg/m^3, M x N = 4 x 16 vortex rings
of uniform size (uniform spacing chordwise and spanwise in both codes), time step dt = c / (M V) (each shed
row one panel long), 200 steps (50 chords of travel), the whole wake kept (no truncation). The compared value
is CL at the last step (lift normal to the free stream over 1/2 rho V^2 S, S = 8 m^2); the CL history is
returned too.

- wingsim: `AeroSolver` of a scene with a prescribed-motion structure holding the wing at alpha (the [wing]
  shorthand, docs/scenes.md), aero.model uvlm-free or uvlm-prescribed, aero.wake_length = inf. The
  structure's coordinates are computed before the timer starts (the wing does not move); the timed part is
  the loop of `AeroSolver.advance` and the read of CL.
- PteraSoftware: a symmetric NACA 0012 section (PteraSoftware meshes the mean camber line, so the lattice
  is the flat plate), a static Movement with delta_time = c / (M V) and the number of steps above,
  max_wake_rows unset (no truncation), `UnsteadyRingVortexLatticeMethodSolver.run` with prescribed_wake
  False (free) or True, no streamlines, no progress bar. The timed part is `run`; building the Movement and
  the UnsteadyProblem (the per-step geometry, made up front) is not timed and reported as values["setup_s"].

Same in both: ring leading segments at the panel quarter chords, collocation points at the three-quarter
chords, the trailing ring's back segment a quarter panel behind the trailing edge (PteraSoftware: 0.25 V dt,
equal to a quarter panel at this step), one wake row shed per step, explicit (forward Euler) convection of
the free wake with the local velocity. Differences that remain (each code's fixed modelling choices):
vortex cores (PteraSoftware: a core of 0.03 c on every ring, growing with the wake ring's age by viscous
and turbulent diffusion; wingsim: Scully cores of 1e-3 (bound) and 0.1 (wake) of the smallest panel
dimension, fixed), the loads (PteraSoftware: Kutta-Joukowski on each ring segment with the local velocity
plus a first-order dGamma/dt term, which is large on its first step since the strengths start from zero;
wingsim: Otsuka et al. 2019, Eqs. 23 and 25, with a second-order dGamma/dt that is zero on the first step).
The CL histories therefore differ over the first steps and agree closely once the start has decayed.

Timing (`Measurement`): wall and CPU time of the stepping only; per_step holds each step's wall time
(PteraSoftware: between the starts of consecutive steps, stamped by a subclass hook; its first step also
builds the bound rings of every step, as its `run` does). Imports and numba compilation are not timed:
before the first timed run of a side in a process, `_warm_up` runs that side once on a 2 x 2 lattice for a
few steps with the same wake model, which compiles PteraSoftware's numba kernels (or loads them from
numba's on-disk cache) and pays wingsim's first-call costs; the same would pay any JIT of wingsim's kernels.
PteraSoftware's numba kernels run on at most 3/4 of numba's threads (one thread on a 2-core machine) and it
limits BLAS to one thread at this panel count; run wingsim with one BLAS thread too (report.process_setup).

Reference (`reference()`): the steady CL of the same wing from a converged vortex-lattice solution, wingsim's
uvlm-flat (quasi-steady rings with flat trailing legs along the stream; steady from its first step) on
8 x 32 and 16 x 64 panels, Richardson-extrapolated in the panel size assuming first order (the ratio of the
successive differences is returned as "observed_ratio" to check it); PteraSoftware's steady ring solver,
extrapolated the same way, is returned beside it as an independent cross-check ("CL_peer_steady").
The unsteady run is compared with a steady value because after 50 chords of travel the start has decayed
(Wagner's function is within 0.2% of its final value at s = 2 V t / c = 100; a finite wing settles sooner)
and the starting vortex is 50 chords away; a refined unsteady run (2x panels each way, half the step) would
hold 12,800 free-wake rings at the end and take hours. For the free wake, the steady reference leaves out
the wake's roll-up; its effect on CL is bounded by the difference between the free and prescribed cases of
one code. The quick size (40 steps, 10 chords) has not reached the steady state: its error includes the start.

    from peer_pterasoftware import cases
    for case in cases(quick=True): print(case.name, case.ours().values["CL"], case.peer_run().values["CL"])
"""
from __future__ import annotations

import time
from functools import cache

import numpy as np
from peer_case import Measurement, PeerCase, Timer

CHORD = 1.0            # m
ASPECT_RATIO = 8.0
ALPHA_DEG = 5.0        # deg
SPEED = 10.0           # m/s
DENSITY = 1.2          # kg/m^3
PANELS = (4, 16)       # chordwise M, spanwise N
STEPS, QUICK_STEPS = 200, 40
REFERENCE_PANELS = ((8, 32), (16, 64))
PEER = "PteraSoftware 5.1"
SECTION = {"thickness": 0.01, "density": 100.0, "youngs_modulus": 1e9, "torsional_rigidity": 1.0}

_warm = set()


def time_step(chordwise):
    """c / (M V), s: each shed wake row one panel long."""
    return CHORD / (chordwise * SPEED)


def wingsim_scene(model, chordwise, spanwise, steps):
    """The resolved wingsim scene: the AR-8 wing held at ALPHA_DEG by a prescribed motion, whole wake kept."""
    from orchestrator.scene.load import resolve_scene

    dt = time_step(chordwise)
    raw = {"time": {"stop": steps * dt}, "coupling": {"step": dt},
           "structure": {"fidelity": "prescribed",
                         "bodies": [{"name": "wing", "span_axis": [0, 1, 0], "chord_axis": [1, 0, 0],
                                     "section": SECTION}]},
           "wing": {"chord": CHORD, "aspect_ratio": ASPECT_RATIO, "alpha_deg": ALPHA_DEG},
           "flow": {"speed": SPEED, "density": DENSITY},
           "aero": {"model": model, "chordwise_panels": chordwise, "spanwise_panels": spanwise,
                    "wake_length": float("inf")}}
    return resolve_scene(raw, "peer_wing")


def run_wingsim(model, chordwise, spanwise, steps):
    """One wingsim run from scratch: Measurement with values {"CL": last CL, "CL_history": [CL per step]}."""
    from aero_fmu.solver import AeroSolver
    from fmu_common.specs import AeroUnitSpec, StructureUnitSpec
    from structure_fmu.solver import StructureSolver

    scene = wingsim_scene(model, chordwise, spanwise, steps)
    dt = time_step(chordwise)
    structure, inputs = StructureSolver(StructureUnitSpec.from_scene(scene)), []
    for k in range(1, steps + 1):
        structure.advance(k * dt)
        inputs.append((k * dt, structure.e.copy(), structure.de.copy()))
    aero = AeroSolver(AeroUnitSpec.from_scene(scene))
    history, per_step = [], []
    with Timer() as timer:
        for t, e, de in inputs:
            start = time.perf_counter()
            aero.advance(t, e, de)
            history.append(aero.outputs()["CL"])
            per_step.append(time.perf_counter() - start)
    return Measurement(timer.wall_s, timer.cpu_s, {"CL": history[-1], "CL_history": history}, per_step)


def pterasoftware_airplane(chordwise, spanwise):
    """PteraSoftware's Airplane of the wing: flat (the symmetric section's camber line), uniform spacing;
    (airplane, wing, its root and tip cross sections). A fresh one per problem (PteraSoftware sets panel
    geometry once per Airplane)."""
    import pterasoftware as ps

    section = ps.geometry.airfoil.Airfoil("naca0012")
    root = ps.geometry.wing_cross_section.WingCrossSection(
        airfoil=section, num_spanwise_panels=spanwise, chord=CHORD, spanwise_spacing="uniform")
    tip = ps.geometry.wing_cross_section.WingCrossSection(
        airfoil=section, num_spanwise_panels=None, chord=CHORD, Lp_Wcsp_Lpp=(0.0, ASPECT_RATIO * CHORD, 0.0))
    wing = ps.geometry.wing.Wing(wing_cross_sections=[root, tip], num_chordwise_panels=chordwise,
                                 chordwise_spacing="uniform")
    return ps.geometry.airplane.Airplane(wings=[wing]), wing, (root, tip)


def operating_point():
    """PteraSoftware's OperatingPoint: V, rho, alpha (the stream turned, the wing in its geometry plane)."""
    import pterasoftware as ps

    return ps.operating_point.OperatingPoint(rho=DENSITY, vCg__E=SPEED, alpha=ALPHA_DEG)


def pterasoftware_problem(chordwise, spanwise, steps):
    """PteraSoftware's UnsteadyProblem of the same wing: static Movement, delta_time = c / (M V), no wake
    truncation (max_wake_rows unset), loads at every step."""
    import pterasoftware as ps

    airplane, wing, sections = pterasoftware_airplane(chordwise, spanwise)
    still = [ps.movements.wing_cross_section_movement.WingCrossSectionMovement(base_wing_cross_section=s)
             for s in sections]
    movement = ps.movements.movement.Movement(
        airplane_movements=[ps.movements.airplane_movement.AirplaneMovement(
            base_airplane=airplane,
            wing_movements=[ps.movements.wing_movement.WingMovement(base_wing=wing,
                                                                    wing_cross_section_movements=still)])],
        operating_point_movement=ps.movements.operating_point_movement.OperatingPointMovement(
            base_operating_point=operating_point()),
        delta_time=time_step(chordwise), num_steps=steps)
    return ps.problems.UnsteadyProblem(movement=movement, only_final_results=False)


@cache
def _stamped_solver():
    """PteraSoftware's unsteady solver recording the wall time at the start of each step (its per-step hook
    `_initialize_step_vortices` runs first in every step of `run`) and at the end of the last step (before
    `_finalize_loads`, which averages the loads after the loop)."""
    from pterasoftware.unsteady_ring_vortex_lattice_method import UnsteadyRingVortexLatticeMethodSolver

    class StampedSolver(UnsteadyRingVortexLatticeMethodSolver):
        __slots__ = ("step_starts",)

        def __init__(self, problem):
            super().__init__(problem)
            self.step_starts = []

        def _initialize_step_vortices(self, step):
            self.step_starts.append(time.perf_counter())
            super()._initialize_step_vortices(step)

        def _finalize_loads(self):
            self.step_starts.append(time.perf_counter())    # the end of the last step
            super()._finalize_loads()

    return StampedSolver


def run_pterasoftware(prescribed_wake, chordwise, spanwise, steps):
    """One PteraSoftware run from scratch: Measurement with values {"CL", "CL_history", "setup_s"}."""
    with Timer() as setup:
        problem = pterasoftware_problem(chordwise, spanwise, steps)
        solver = _stamped_solver()(problem)
    with Timer() as timer:
        solver.run(prescribed_wake=prescribed_wake, calculate_streamlines=False, show_progress=False)
    per_step = np.diff(solver.step_starts).tolist()
    # Wind axes: PteraSoftware's force coefficient z points down, lift is its negative.
    history = [-float(p.airplanes[0].forceCoefficients_W[2]) for p in problem.steady_problems]
    return Measurement(timer.wall_s, timer.cpu_s, {"CL": history[-1], "CL_history": history,
                                                   "setup_s": setup.wall_s}, per_step)


def _warm_up(side, free):
    """Run a side once on a 2 x 2 lattice (numba compilation or cache load, first-call costs), untimed."""
    if (side, free) in _warm:
        return
    if side == "peer":
        run_pterasoftware(not free, 2, 2, 4)
    else:
        run_wingsim("uvlm-free" if free else "uvlm-prescribed", 2, 2, 4)
    _warm.add((side, free))


def steady_cl(chordwise, spanwise):
    """Steady CL of the wing from wingsim's uvlm-flat (one step: quasi-steady, no wake memory)."""
    from aero_fmu.solver import AeroSolver
    from fmu_common.specs import AeroUnitSpec, StructureUnitSpec
    from structure_fmu.solver import StructureSolver

    scene = wingsim_scene("uvlm-flat", chordwise, spanwise, 1)
    structure = StructureSolver(StructureUnitSpec.from_scene(scene))
    structure.advance(time_step(chordwise))
    aero = AeroSolver(AeroUnitSpec.from_scene(scene))
    aero.advance(time_step(chordwise), structure.e, structure.de)
    return aero.outputs()["CL"]


def pterasoftware_steady_cl(chordwise, spanwise):
    """Steady CL of the same wing from PteraSoftware's steady ring vortex-lattice solver (a cross-check of the
    reference by an independent code)."""
    import pterasoftware as ps

    problem = ps.problems.SteadyProblem(airplanes=[pterasoftware_airplane(chordwise, spanwise)[0]],
                                        operating_point=operating_point())
    ps.steady_ring_vortex_lattice_method.SteadyRingVortexLatticeMethodSolver(problem).run(calculate_streamlines=False)
    return -float(problem.airplanes[0].forceCoefficients_W[2])


def _extrapolate(cl):
    """Richardson extrapolation, first order in the panel size, of {(M, N): CL} over PANELS and REFERENCE_PANELS:
    (extrapolated CL, observed ratio of successive differences, 2 for first order)."""
    base, coarse, fine = cl[PANELS], *(cl[mn] for mn in REFERENCE_PANELS)
    return 2.0 * fine - coarse, (base - coarse) / (coarse - fine)


@cache
def reference():
    """{"CL": wingsim's steady CL extrapolated from REFERENCE_PANELS, "observed_ratio": its ratio of
    successive differences (2 for first order), "CL_steady": {"MxN": CL} of each lattice,
    "CL_peer_steady", "peer_observed_ratio": the same by PteraSoftware's steady solver (cross-check)}.
    Computed once per process."""
    lattices = (PANELS, *REFERENCE_PANELS)
    ours = {mn: steady_cl(*mn) for mn in lattices}
    peer = {mn: pterasoftware_steady_cl(*mn) for mn in lattices}
    (cl, ratio), (peer_cl, peer_ratio) = _extrapolate(ours), _extrapolate(peer)
    return {"CL": cl, "observed_ratio": ratio, "CL_steady": {f"{m}x{n}": v for (m, n), v in ours.items()},
            "CL_peer_steady": peer_cl, "peer_observed_ratio": peer_ratio}


def errors(values, ref):
    """{"CL_last": relative error of CL at the last step against the reference CL}."""
    return {"CL_last": abs(values["CL"] - ref["CL"]) / abs(ref["CL"])}


def _side(side, free, steps):
    def run():
        _warm_up(side, free)
        if side == "peer":
            return run_pterasoftware(not free, *PANELS, steps)
        return run_wingsim("uvlm-free" if free else "uvlm-prescribed", *PANELS, steps)
    return run


def cases(quick=False):
    """The peer cases; quick: 40 steps instead of 200 (the start not finished: see the module doc)."""
    steps = QUICK_STEPS if quick else STEPS
    m, n = PANELS
    what = (f"flat plate c = {CHORD:g} m, AR {ASPECT_RATIO:g}, alpha {ALPHA_DEG:g} deg, V = {SPEED:g} m/s, "
            f"rho = {DENSITY:g} kg/m^3; {m} x {n} uniform rings; dt = c/(MV); {steps} steps; whole wake; "
            "CL at the last step against a converged steady VLM")
    out = []
    for free, label, how in ((True, "free", "explicit rollup"), (False, "prescribed", "convected with the stream")):
        out.append(PeerCase(
            name=f"UVLM {label} wake, AR 8 flat plate, {m} x {n} panels, {steps} steps, no truncation",
            peer=PEER, what=f"{what}; wake {how}", ours=_side("ours", free, steps),
            peer_run=_side("peer", free, steps), reference=reference, errors=errors, target=0.1 if free else None))
    return out


CASES: list[PeerCase] = cases()   # building them imports nothing: PteraSoftware is imported when a case runs
