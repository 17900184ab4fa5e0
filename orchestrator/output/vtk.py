"""The geometry history of a run for ParaView (``wingsim run --vtk``): VTK XML unstructured grids, one ``.vtu``
per frame, and a ``.pvd`` collection per part that lists them with their times (open the ``.pvd`` in ParaView and
play it). Written with numpy and the standard library (ASCII data arrays), into ``OUT/vtk/``:

- ``structure.pvd`` and ``structure_<frame>.vtu``: the structure's nodes (points: r, m, global frame) and its
  elements (cells: VTK_LINE from node A to node B), with the cell data ``body`` (the body's index in the scene's
  order, named in the file's ``FieldData`` ``bodies``) and the point data ``node`` (the node's index);
- ``lattice.pvd`` and ``lattice_<frame>.vtu`` (scenes with an aero unit): the wing's panels and the shed wake's
  vortex rings (cells: VTK_QUAD, corners in the lattice's order), with the cell data ``part`` (0 wing, 1 wake) and
  ``circulation`` (m^2/s of the wake rings, 0 on the wing panels); none at t = 0, before the first aero step.

The frames are ``VTK_FRAMES`` instants evenly spread over the run (``orchestrator.output.geometry_history``, which
also says where the lattice comes from and what limits it).
"""

from __future__ import annotations

import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from orchestrator.files import write_file
from orchestrator.output.geometry_history import Frame, geometry_history

VTK_FOLDER = "vtk"
VTK_FRAMES = 101
VTK_LINE, VTK_QUAD = 3, 9
"""VTK cell types of a 2-point line and of a quadrilateral."""


def _array(parent: ET.Element, name: str | None, values: np.ndarray, vtk_type: str, components: int = 1) -> None:
    """A DataArray of ``values`` (flattened, ASCII) under ``parent``."""
    attributes = {"type": vtk_type, "format": "ascii"}
    if name is not None:
        attributes["Name"] = name
    if components > 1:
        attributes["NumberOfComponents"] = str(components)
    array = ET.SubElement(parent, "DataArray", attributes)
    flat = np.asarray(values).ravel()
    # 12 significant digits, as timeseries.csv
    array.text = " ".join(f"{v:.12g}" for v in flat) if vtk_type.startswith("Float") else " ".join(map(str, flat))


def unstructured_grid(points: np.ndarray, cells: np.ndarray, cell_type: int, cell_data: dict[str, np.ndarray],
                      point_data: dict[str, np.ndarray] | None = None,
                      field_data: dict[str, list[str]] | None = None) -> ET.ElementTree:
    """A VTK XML UnstructuredGrid of one cell type.

    Args:
        points: (P, 3) m.
        cells: (C, k) point indices of each cell.
        cell_type: the VTK cell type of every cell (VTK_LINE, VTK_QUAD).
        cell_data: {name: (C,)} values per cell (integers written as Int32, else Float64).
        point_data: {name: (P,)} values per point, likewise.
        field_data: {name: [strings]} written as a String array (e.g. the bodies' names).
    """
    cells = np.asarray(cells, dtype=np.int64).reshape(len(cells), -1)
    root = ET.Element("VTKFile", {"type": "UnstructuredGrid", "version": "1.0", "byte_order": "LittleEndian",
                                  "header_type": "UInt64"})
    grid = ET.SubElement(root, "UnstructuredGrid")
    if field_data:
        fields = ET.SubElement(grid, "FieldData")
        for name, strings in field_data.items():
            text = ET.SubElement(fields, "DataArray", {"type": "String", "Name": name, "format": "ascii",
                                                       "NumberOfTuples": str(len(strings))})
            text.text = " ".join(" ".join(str(b) for b in s.encode()) + " 0" for s in strings)
    piece = ET.SubElement(grid, "Piece", {"NumberOfPoints": str(len(points)), "NumberOfCells": str(len(cells))})
    _array(ET.SubElement(piece, "Points"), None, np.asarray(points, dtype=float).reshape(-1, 3), "Float64", 3)
    topology = ET.SubElement(piece, "Cells")
    _array(topology, "connectivity", cells, "Int64")
    _array(topology, "offsets", np.arange(1, len(cells) + 1) * cells.shape[1], "Int64")
    _array(topology, "types", np.full(len(cells), cell_type), "UInt8")
    for tag, data in (("PointData", point_data or {}), ("CellData", cell_data)):
        block = ET.SubElement(piece, tag)
        for name, values in data.items():
            values = np.asarray(values)
            _array(block, name, values, "Int32" if np.issubdtype(values.dtype, np.integer) else "Float64")
    return ET.ElementTree(root)


def structure_grid(frame: Frame) -> ET.ElementTree:
    """The structure of a frame: nodes and elements (module docstring)."""
    return unstructured_grid(frame.nodes, frame.elements, VTK_LINE, {"body": frame.element_body},
                             {"node": np.arange(len(frame.nodes))}, {"bodies": frame.bodies})


def _quads(grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(points (P, 3), quads (Q, 4)) of a structured grid (B, rows, cols, 3), quads row-major per body."""
    grid = np.asarray(grid, dtype=float)
    blocks, rows, cols = grid.shape[:3]
    index = np.arange(blocks * rows * cols).reshape(blocks, rows, cols)
    quads = np.stack([index[:, :-1, :-1], index[:, 1:, :-1], index[:, 1:, 1:], index[:, :-1, 1:]], axis=-1)
    return grid.reshape(-1, 3), quads.reshape(-1, 4)


def lattice_grid(frame: Frame) -> ET.ElementTree:
    """The lattice of a frame: wing panels and wake rings (module docstring)."""
    points, quads = _quads(frame.wing)
    part, gamma = np.zeros(len(quads), dtype=int), np.zeros(len(quads))
    if frame.wake is not None and frame.wake.shape[1] > 1:
        wake_points, wake_quads = _quads(frame.wake)
        quads = np.concatenate([quads, wake_quads + len(points)])
        points = np.concatenate([points, wake_points])
        part = np.concatenate([part, np.ones(len(wake_quads), dtype=int)])
        gamma = np.concatenate([gamma, np.asarray(frame.wake_gamma, dtype=float).ravel()])
    return unstructured_grid(points, quads, VTK_QUAD, {"part": part, "circulation": gamma})


def collection(entries: list[tuple[float, str]]) -> ET.ElementTree:
    """A ParaView collection (.pvd) of (time s, file name) entries."""
    root = ET.Element("VTKFile", {"type": "Collection", "version": "0.1", "byte_order": "LittleEndian"})
    listing = ET.SubElement(root, "Collection")
    for time, name in entries:
        ET.SubElement(listing, "DataSet", {"timestep": f"{time:.12g}", "group": "", "part": "0", "file": name})
    return ET.ElementTree(root)


def _write(tree: ET.ElementTree, path: Path) -> Path:
    return write_file(path, lambda tmp: tree.write(tmp, encoding="utf-8", xml_declaration=True))


def write_vtk(result, out_dir, frames: int = VTK_FRAMES, budget_s: float | None = None,
              history: tuple[list[Frame], str] | None = None) -> list[Path]:
    """Write ``OUT/vtk/`` (module docstring) for a run with recorded structure coordinates; returns the files
    written (the .pvd collections last), [] when nothing was recorded. Files of an earlier run there are removed
    first.

    Args:
        result: the RunResult.
        out_dir: the run's output folder.
        frames: instants written, evenly spread over the run.
        budget_s: wall time (s) of the aero replay (``geometry_history``).
        history: the (frames, note) of ``geometry_history`` when already computed (``shared_histories``).
    """
    folder = Path(out_dir) / VTK_FOLDER
    history, note = history if history is not None else geometry_history(result, frames, budget_s)
    folder.mkdir(parents=True, exist_ok=True)
    for stale in (*folder.glob("*.vtu"), *folder.glob("*.pvd")):
        stale.unlink()
    if not history:
        return []
    if note:
        print(f"note: {VTK_FOLDER}/: {note}", file=sys.stderr)
    width = max(4, len(str(len(history) - 1)))
    written, structure, lattice = [], [], []
    for k, frame in enumerate(history):
        name = f"structure_{k:0{width}d}.vtu"
        written.append(_write(structure_grid(frame), folder / name))
        structure.append((frame.time, name))
        if frame.wing is not None:
            name = f"lattice_{k:0{width}d}.vtu"
            written.append(_write(lattice_grid(frame), folder / name))
            lattice.append((frame.time, name))
    written.append(_write(collection(structure), folder / "structure.pvd"))
    if lattice:
        written.append(_write(collection(lattice), folder / "lattice.pvd"))
    return written
