"""The two-body system of Otsuka et al. 2022, Sec. 4.4 (scenes/two_body_003.toml): the RMS of the free end's Z
(Eq. 24) converges with the number of sections (Eq. 23) in the strain-based and the ANCF fidelity, and agrees
with an independent planar finite-segment chain (tests/finite_segment_chain.py, refined and Richardson-
extrapolated: 10.135858 m over 0-5 s, order 2).

The slow set runs the paper's 0-5 s; the default set the first second, against the chain at 12, 24 and 48
segments per body extrapolated the same way."""
import numpy as np
import pytest

import finite_segment_chain
from orchestrator.scene.load import load_scene
from repository import SCENES
from structure_fmu.solver import StructureSolver
from fmu_common.specs import StructureUnitSpec

SAMPLE = 0.01        # s, Eq. (24)'s sampling


def free_end_z(fidelity, elements, stop):
    """Z (m) of B's free end at t = 0, 0.01, ..., stop s."""
    solver = StructureSolver(StructureUnitSpec.from_scene(load_scene(SCENES / "two_body_003.toml", [
        f"structure.fidelity={fidelity}", f"structure.elements_per_body={elements}", f"time.stop={stop}"])))
    z = []
    for k in range(int(round(stop / SAMPLE)) + 1):
        solver.advance(k * SAMPLE)
        z.append(solver.e.reshape(-1, 3, 3)[-1, 0, 2])
    return np.array(z)


def rms(z):
    """Otsuka et al. 2022, Eq. (24)."""
    return float(np.sqrt(np.mean(z ** 2)))


def test_first_second_against_the_finite_segment_chain():
    """0-1 s: the chain's RMS extrapolated from 12, 24, 48 segments (observed order ~2); the strain-based beam's
    error falls about four times per doubling (constant curvature per element: second order) and is within 1e-3
    at 12 elements; the ANCF beam (cubic elements) within 1e-4 already at 6."""
    times = np.arange(101) * SAMPLE
    reference, order, _ = finite_segment_chain.richardson(
        (12, 24, 48), [rms(finite_segment_chain.free_end_z(n, times)) for n in (12, 24, 48)])
    assert order == pytest.approx(2.0, abs=0.1)
    errors = [abs(rms(free_end_z("strain-based", n, 1.0)) / reference - 1) for n in (3, 6, 12)]
    assert errors[0] / errors[1] > 3 and errors[1] / errors[2] > 3
    assert errors[2] < 1e-3
    assert abs(rms(free_end_z("flexible", 6, 1.0)) / reference - 1) < 1e-4


@pytest.fixture(scope="module")
def paper_runs():
    """{(fidelity, sections): RMS (m)} over 0-5 s, and the chain's extrapolated RMS under "reference"."""
    runs = {(f, n): rms(free_end_z(f, n, 5.0)) for f in ("strain-based", "flexible") for n in (6, 50)}
    return {**runs, "reference": finite_segment_chain.extrapolated_rms().value}


@pytest.mark.slow
@pytest.mark.parametrize("fidelity, limit", [("strain-based", 1e-2), ("flexible", 1e-3)])
def test_rms_error_at_six_sections(paper_runs, fidelity, limit):
    """Otsuka et al. 2022, Eq. (23): |RMS(50) - RMS(6)| / RMS(50) below 1% (strain-based; the paper's six sections
    were visibly converged) and below 1e-3 (ANCF)."""
    assert abs(paper_runs[fidelity, 50] - paper_runs[fidelity, 6]) / paper_runs[fidelity, 50] < limit


@pytest.mark.slow
@pytest.mark.parametrize("fidelity", ["strain-based", "flexible"])
def test_converged_rms_agrees_with_the_finite_segment_chain(paper_runs, fidelity):
    assert paper_runs[fidelity, 50] == pytest.approx(paper_runs["reference"], rel=2e-3)
