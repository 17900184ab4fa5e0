"""Biot-Savart law of straight vortex segments (Otsuka et al. 2019, Eq. 19) against closed forms; the vortex core;
the compiled (C) kernels against the numpy reference, and how their library is compiled, cached and found."""
import ctypes
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse

from aero_fmu import biot_savart
from aero_fmu.biot_savart import induced_velocity, influence, segment_velocity

RNG = np.random.default_rng(5)


def test_finite_segment_matches_the_classical_formula():
    """Segment on the x axis from x = a to x = b, point (x, h, 0): v = Gamma / (4 pi h) (cos t1 - cos t2) e_z
    with cos t1 = (x - a) / |r1|, cos t2 = (x - b) / |r2| (the textbook straight-segment form; e_z = e_x x e_y).
    With the Scully core delta the magnitude is multiplied by h^2 / (h^2 + delta^2) exactly."""
    a, b, h, gamma = -0.3, 1.1, 0.25, 2.0
    x = np.array([-2.0, -0.3, 0.2, 1.1, 4.0])
    points = np.stack([x, np.full_like(x, h), np.zeros_like(x)], axis=1)
    cos1 = (x - a) / np.hypot(x - a, h)
    cos2 = (x - b) / np.hypot(x - b, h)
    expected = gamma / (4 * np.pi * h) * (cos1 - cos2)
    v = induced_velocity(points, [[a, 0, 0]], [[b, 0, 0]], [gamma])
    np.testing.assert_allclose(v[:, 2], expected, rtol=1e-13)
    np.testing.assert_allclose(v[:, :2], 0.0, atol=1e-16)
    delta = 0.01
    v_core = induced_velocity(points, [[a, 0, 0]], [[b, 0, 0]], [gamma], core=delta)
    np.testing.assert_allclose(v_core[:, 2], expected * h**2 / (h**2 + delta**2), rtol=1e-13)


def test_semi_infinite_segment_closed_form_and_limit():
    """Semi-infinite vortex from the origin along +x, point (x, h, 0): v = Gamma / (4 pi h) (1 + x / |r1|) e_z,
    i.e. Gamma / (4 pi h) abreast of its start and Gamma / (2 pi h) (the infinite line) far downstream.
    A finite segment 1e6 h long gives the same to 1e-9."""
    h = 0.4
    x = np.array([-3.0, 0.0, 0.7, 1e7])
    points = np.stack([x, np.full_like(x, h), np.zeros_like(x)], axis=1)
    v = segment_velocity(points, [[0, 0, 0]], [[1.0, 0, 0]], semi_infinite=True)[:, 0]
    np.testing.assert_allclose(v[:, 2], (1 + x / np.hypot(x, h)) / (4 * np.pi * h), rtol=1e-13)
    assert v[1, 2] == pytest.approx(1 / (4 * np.pi * h), rel=1e-14)
    assert v[3, 2] == pytest.approx(1 / (2 * np.pi * h), rel=1e-12)
    long = segment_velocity(points[:3], [[0, 0, 0]], [[1e6 * h, 0, 0]])[:, 0]
    np.testing.assert_allclose(long, v[:3], rtol=1e-9)


@pytest.mark.parametrize("core", [0.0, 1e-3])
def test_points_on_a_segment_or_its_extension_get_a_finite_zero_velocity(core):
    """On the line of a straight filament (middle, ends, extension both sides) the principal value of its
    own induced velocity is zero; the kernel returns exactly that, never NaN/inf, with or without a core.
    A zero-length segment induces nothing. Just off the line the core bounds the speed by 1/(4 pi delta)."""
    on_line = np.array([[0.5, 0, 0], [0, 0, 0], [1, 0, 0], [-2, 0, 0], [3, 0, 0]], dtype=float)
    v = segment_velocity(on_line, [[0, 0, 0]], [[1, 0, 0]], core)
    assert np.all(v == 0.0)
    v = segment_velocity(on_line, [[0, 0, 0]], [[1, 0, 0]], core, semi_infinite=True)
    assert np.all(v == 0.0)
    v = segment_velocity(RNG.random((4, 3)), [[0.2, 0.2, 0.2]], [[0.2, 0.2, 0.2]], core)
    assert np.all(v == 0.0)
    if core:
        near = np.array([[0.5, 1e-12, 0], [0.5, core, 0], [0.5, 1e-300, 0]])
        v = segment_velocity(near, [[0, 0, 0]], [[1, 0, 0]], core)
        assert np.all(np.isfinite(v)) and np.max(np.abs(v)) <= 1 / (4 * np.pi * core)


def test_blocked_influence_equals_the_dense_tensor(monkeypatch):
    """`influence` (blocked, reduced by sparse weights) equals the plain (P, S, 3) tensor contracted by hand."""
    P, S, K = 37, 23, 9
    points, starts, ends = RNG.random((P, 3)), RNG.random((S, 3)), RNG.random((S, 3))
    normals = RNG.standard_normal((P, 3))
    weights = scipy.sparse.random(S, K, density=0.3, format="csr", random_state=3)
    monkeypatch.setattr(biot_savart, "BLOCK_PAIRS", 50)   # several blocks of 2 points
    tensor = segment_velocity(points, starts, ends, 1e-3)
    dense = weights.toarray()
    np.testing.assert_allclose(influence(points, starts, ends, weights, 1e-3),
                               np.einsum("psc,sk->pck", tensor, dense), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(influence(points, starts, ends, weights, 1e-3, normals=normals),
                               np.einsum("psc,pc,sk->pk", tensor, normals, dense), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("semi_infinite", [False, True])
def test_the_compiled_kernels_equal_the_numpy_reference(kernels, semi_infinite):
    """Both kernels on every path of `influence` (normal wash, velocities per unknown, known circulations), with
    the singular cases mixed in (points at segment ends, zero-length segments): equal to 1e-12 of the largest
    value (the normal wash bit for bit: the same operations in the same order)."""
    P, S, K = 41, 67, 11
    points, starts = RNG.standard_normal((P, 3)), RNG.standard_normal((S, 3))
    ends = RNG.standard_normal((S, 3))
    if semi_infinite:
        ends /= np.linalg.norm(ends, axis=1)[:, None]
    else:
        ends[:4] = starts[:4]                                  # zero-length segments
    points[:3] = starts[5:8]                                   # points at segment starts
    normals = RNG.standard_normal((P, 3))
    weights = scipy.sparse.random(S, K, density=0.2, format="csr", random_state=4)
    gamma = RNG.standard_normal((S, 1))
    results = {}
    for kind in ("numpy", "compiled"):
        kernels(kind)
        results[kind] = [influence(points, starts, ends, weights, 1e-3, semi_infinite, normals),
                         influence(points, starts, ends, weights, 1e-3, semi_infinite),
                         influence(points, starts, ends, gamma, 1e-3, semi_infinite)]
    for reference, compiled in zip(results["numpy"], results["compiled"]):
        assert np.abs(compiled - reference).max() <= 1e-12 * np.abs(reference).max()
    np.testing.assert_array_equal(results["compiled"][0], results["numpy"][0])


@pytest.mark.parametrize("semi_infinite", [False, True])
def test_the_compiled_sum_over_blocks_of_points_equals_the_numpy_reference(kernels, semi_infinite):
    """Known circulations summed at more points than two blocks of the compiled sum (a partial block last), some
    circulations zero (skipped by the compiled sum): every point equals the numpy reference to 1e-12 of the
    largest value."""
    kernels("compiled")
    point_block = ctypes.c_long.in_dll(biot_savart.c_kernels(), "point_block").value
    P, S = 2 * point_block + 37, 29
    points, starts, ends = RNG.standard_normal((P, 3)), RNG.standard_normal((S, 3)), RNG.standard_normal((S, 3))
    if semi_infinite:
        ends /= np.linalg.norm(ends, axis=1)[:, None]
    gamma = RNG.standard_normal((S, 1))
    gamma[::4] = 0.0
    fast = induced_velocity(points, starts, ends, gamma, 1e-3, semi_infinite)
    kernels("numpy")
    reference = induced_velocity(points, starts, ends, gamma, 1e-3, semi_infinite)
    assert np.abs(fast - reference).max() <= 1e-12 * np.abs(reference).max()


@pytest.mark.parametrize("semi_infinite", [False, True])
def test_the_compiled_kernels_keep_the_core_behaviour_on_and_near_a_segment(kernels, semi_infinite):
    """The compiled kernels on the singular points of the module docstring, on every path of `influence`: on the
    segment's line (middle, ends, extension both sides) exactly zero, never NaN/inf; from 1e-300 to delta off the
    line finite and at most 1 / (4 pi delta) per unit circulation; a zero-length segment induces nothing
    (finite segments); all equal to the numpy reference to 1e-12 of the largest value."""
    core = 1e-3
    on_line = np.array([[0.5, 0, 0], [0, 0, 0], [1, 0, 0], [-2, 0, 0], [3, 0, 0]])
    near = np.array([[0.5, 1e-300, 0], [0.5, 0, 1e-300], [0.5, 1e-12, 0], [0.5, core, 0], [0, core, 0]])
    points = np.concatenate([on_line, near])
    starts, ends = np.array([[0.0, 0, 0], [0.2, 0.2, 0.2]]), np.array([[1.0, 0, 0], [0.2, 0.2, 0.2]])
    if semi_infinite:
        starts, ends = starts[:1], ends[:1]                    # a direction, never of zero length
    normals = RNG.standard_normal((len(points), 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    unit, gamma = np.eye(len(starts)), np.ones((len(starts), 1))
    results = {}
    for kind in ("numpy", "compiled"):
        kernels(kind)
        results[kind] = [influence(points, starts, ends, unit, core, semi_infinite, normals),
                         influence(points, starts, ends, unit, core, semi_infinite),
                         influence(points, starts, ends, gamma, core, semi_infinite)]
    for reference, fast in zip(results["numpy"], results["compiled"]):
        assert np.all(np.isfinite(fast))
        assert np.all(fast[:len(on_line)] == 0.0)
        assert np.abs(fast).max() <= 1 / (4 * np.pi * core)
        assert np.abs(fast - reference).max() <= 1e-12 * np.abs(reference).max()
    # at h = delta the swirl h / (h^2 + delta^2) peaks at 1 / (2 delta): mid-segment (both ends far) the speed is
    # 1 / (4 pi delta), abreast of the start half of it (finite or semi-infinite)
    speeds = np.linalg.norm(results["compiled"][1][len(on_line):], axis=1)      # (near, segments)
    assert speeds[3, 0] == pytest.approx(1 / (4 * np.pi * core), rel=1e-5)
    assert speeds[4, 0] == pytest.approx(1 / (8 * np.pi * core), rel=1e-5)
    if not semi_infinite:
        assert np.all(speeds[:, 1] == 0.0)


LOAD_PROBE = """
import sys
from fmu_common import c_library
print(c_library.load(sys.argv[1])._name)
"""


def _load_in_a_process(source, cache, **env):
    """The path of the library a fresh process loads for the C file `source`, with the cache folder `cache`."""
    env = {**os.environ, "WINGSIM_CACHE_DIR": str(cache), "WINGSIM_KERNELS": "compiled", **env}
    return subprocess.run([sys.executable, "-c", LOAD_PROBE, str(source)], env=env, capture_output=True, text=True,
                          check=True).stdout.strip()


def test_the_c_kernels_are_compiled_once_per_machine_whatever_folder_they_run_from(tmp_path):
    """An FMU unpacks its sources into a fresh folder at every instantiation: the C file run from two folders is
    compiled once, into the cache folder, and the second process loads that library without compiling (without
    a compiler: $CC names none)."""
    cache = tmp_path / "cache"
    sources = []
    for unpacked in ("fmu_a", "fmu_b"):
        (tmp_path / unpacked).mkdir()
        sources.append(tmp_path / unpacked / biot_savart.C_SOURCE.name)
        sources[-1].write_bytes(biot_savart.C_SOURCE.read_bytes())
    first = _load_in_a_process(sources[0], cache)
    second = _load_in_a_process(sources[1], cache, CC=str(tmp_path / "no-such-cc"))
    assert first == second and first.startswith(str(cache))
    assert sorted(p.name for p in cache.iterdir()) == [Path(first).name, Path(first).name + ".sha256"]


def test_a_library_beside_its_source_is_loaded_first_and_a_changed_source_gets_a_new_one(tmp_path):
    """A built FMU carries each C kernel's library beside its source: it is loaded from there, with no compiler
    and nothing written to the cache. An edited source is another library (its name carries the digest)."""
    from fmu_common import c_library

    source = tmp_path / "fmu" / biot_savart.C_SOURCE.name
    source.parent.mkdir()
    source.write_bytes(biot_savart.C_SOURCE.read_bytes())
    built = c_library.compile_into(source, source.parent)
    cache = tmp_path / "cache"
    assert _load_in_a_process(source, cache, CC=str(tmp_path / "no-such-cc")) == str(built)
    assert not cache.exists()
    source.write_bytes(source.read_bytes() + b"\n/* edited */\n")
    assert c_library.library_name(source) != built.name


def test_an_unknown_kernel_choice_is_refused_naming_the_variable(monkeypatch):
    from fmu_common import compiled

    monkeypatch.setenv("WINGSIM_KERNELS", "fast")
    with pytest.raises(ValueError, match="WINGSIM_KERNELS"):
        compiled.selected()


def test_a_compilation_started_in_the_background_is_awaited_and_its_errors_reported_where_needed(tmp_path,
                                                                                                 monkeypatch):
    """`start_compiling` returns at once; `library_file` then waits for that compilation and gives the library in
    the cache folder, or raises the compiler's error (a source that does not compile) naming the numpy choice."""
    from fmu_common import c_library

    monkeypatch.setenv("WINGSIM_CACHE_DIR", str(tmp_path / "cache"))
    good, bad = tmp_path / "good.c", tmp_path / "bad.c"
    good.write_text("double twice(double x) { return 2.0 * x; }\n")
    bad.write_text("double twice(double x) { return 2.0 * ; }\n")
    for source in (good, bad):
        c_library.start_compiling(source)
    library = c_library.library_file(good)
    assert library == tmp_path / "cache" / c_library.library_name(good)
    twice = ctypes.CDLL(str(library)).twice
    twice.restype, twice.argtypes = ctypes.c_double, [ctypes.c_double]
    assert twice(1.25) == 2.5
    with pytest.raises(c_library.CLibraryUnavailable, match="(?s)bad.c.*error.*WINGSIM_KERNELS=numpy"):
        c_library.library_file(bad)


def test_a_process_that_ends_before_its_compilation_leaves_no_partial_file(tmp_path):
    """A command that started the C kernels' compilation and ended first (a scene error, say) stops the compiler
    at exit: neither the cache folder nor the temporary folder holds a partial library."""
    cache, temporary = tmp_path / "cache", tmp_path / "tmp"
    temporary.mkdir()
    code = ("from fmu_common import c_library\nfrom aero_fmu.biot_savart import C_SOURCE\n"
            "c_library.start_compiling(C_SOURCE)\n")
    subprocess.run([sys.executable, "-c", code], env={**os.environ, "WINGSIM_CACHE_DIR": str(cache),
                                                      "TMPDIR": str(temporary)}, check=True)
    assert not cache.exists() or list(cache.iterdir()) == []
    assert list(temporary.iterdir()) == []
