"""Reading meshes, atomic writes, and ``.pvd`` time series that PyVista and ParaView animate."""

from __future__ import annotations

import math
import os
import re
import shutil
import tempfile
import warnings
from pathlib import Path
from xml.etree import ElementTree
from xml.sax.saxutils import quoteattr

import numpy as np
import pyvista as pv
from vtkmodules.vtkCommonCore import vtkObject

from pverosion.kernels.files import atomic_path, file_mode

__all__ = [
    "EXTENSIONS",
    "OUTPUT_FORMATS",
    "SURFACE_ONLY",
    "TimeSeriesWriter",
    "atomic_path",
    "blocks_folder",
    "check_output_path",
    "check_writable",
    "read_dataset",
    "read_image",
    "read_mesh",
    "write_atomic",
]

EXTENSIONS = {
    "PolyData": ".vtp",
    "ImageData": ".vti",
    "UnstructuredGrid": ".vtu",
    "StructuredGrid": ".vts",
    "RectilinearGrid": ".vtr",
    "MultiBlock": ".vtm",
}
"""XML VTK extension used for each PyVista dataset type."""

OUTPUT_FORMATS = {"vtkPolyData": (".vtp", ".vtk", ".ply", ".stl", ".obj"), "vtkImageData": (".vti", ".vtk"),
                  "vtkMultiBlockDataSet": (".vtm",)}
"""File suffixes each output data type can be written as (the first is the recommended one); those in
:data:`SURFACE_ONLY` lose the arrays."""

SURFACE_ONLY = (".ply", ".stl", ".obj")
"""Surface suffixes that keep the points and faces only, not the point, cell and field arrays (the curvature,
displacement, statistics); :func:`write_atomic` warns when it drops arrays."""


def check_output_path(path: str | os.PathLike, data_type: str, *, what: str = "output") -> Path:
    """Check, before any work, that a ``data_type`` result can be written to ``path``.

    Parameters
    ----------
    path : str or path-like
    data_type : {"vtkPolyData", "vtkImageData", "vtkMultiBlockDataSet"}
        VTK class name of the result.
    what : str
        How the path is named in messages (e.g. ``"-o"``).

    Returns
    -------
    pathlib.Path

    Raises
    ------
    ValueError
        If the suffix cannot hold the result, the path is a folder, or its
        folder cannot be created or written.
    """
    path = Path(path)
    suffixes = OUTPUT_FORMATS[data_type]
    if path.suffix.lower() not in suffixes:
        got = f"{path.suffix!r}" if path.suffix else "no extension"
        name = data_type[3:]
        article = "an" if name[0] in "AEIOU" else "a"
        raise ValueError(f"{what} {path}: {article} {name} result is written as {', '.join(suffixes)}; got {got}")
    return check_writable(path, what)


def check_writable(path: str | os.PathLike, what: str = "output") -> Path:
    """Check, before any work, that a file can be created or replaced at ``path``.

    The nearest existing folder of ``path`` is tried by creating (and at once
    removing) a temporary file in it, so read-only file systems, access
    control lists and folders where files cannot be made are caught too, not
    only missing permission bits (which do not bind the superuser).

    Parameters
    ----------
    path : str or path-like
    what : str
        How the path is named in messages (e.g. ``"--screenshot"``).

    Returns
    -------
    pathlib.Path

    Raises
    ------
    ValueError
        If ``path`` is a folder, or its nearest existing folder is not a
        folder or does not take a new file.
    """
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{what} {path}: is a folder; give a file name")
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise ValueError(f"{what} {path}: {parent} is not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=".pverosion-probe.", dir=parent)
    except OSError as exc:
        raise ValueError(f"{what} {path}: cannot write in {parent} ({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(probe)
    return path


_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}


def _check_ply(path: Path) -> None:
    """``ValueError`` if the PLY file ``path`` holds fewer elements than its header announces.

    VTK's PLY reader does not check this: a truncated binary file crashed
    the process and a truncated text file gave empty faces.
    """
    with open(path, "rb") as file:
        head = file.read(65536)
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        raise ValueError(f"cannot read {path}: not a PLY file (no 'ply' ... 'end_header' header)")
    lines = head[:end].decode("ascii", "replace").splitlines()
    words = [line.split() for line in lines if line.split()]
    fmt = next((w[1] for w in words if w[0] == "format" and len(w) > 1), "")
    elements: list[tuple[str, int, list[list[str]]]] = []
    for w in words:
        if w[0] == "element" and len(w) == 3 and w[2].isdigit():
            elements.append((w[1], int(w[2]), []))
        elif w[0] == "property" and elements:
            elements[-1][2].append(w[1:])
    start = head.index(b"\n", end) + 1 if b"\n" in head[end:] else len(head)
    data = np.memmap(path, dtype=np.uint8, mode="r", offset=start) if path.stat().st_size > start else np.zeros(0, np.uint8)
    if fmt == "ascii":
        # lines, blank ones included (never fewer than the records; no copy of the data)
        have = int(np.count_nonzero(data == ord("\n"))) + int(len(data) > 0 and data[-1] != ord("\n"))
        need = sum(count for _, count, _ in elements)
    else:
        order = ">" if fmt == "binary_big_endian" else "<"
        need = _ply_binary_size(data, elements, order)
        have = len(data)
    if have < need:
        unit = "lines" if fmt == "ascii" else "bytes"
        announced = ", ".join(f"{count} {name}" for name, count, _ in elements)
        raise ValueError(f"cannot read {path}: the file is truncated: its header announces {announced} elements, "
                         f"more than the {have} {unit} of data after it hold")


_GRID_ATTRIBUTES = ("Origin", "Spacing", "Direction")


def _check_vti(path: Path) -> None:
    """``ValueError`` if the grid of the VTK XML image ``path`` has a non-finite origin, spacing or direction.

    VTK's XML reader reads ``nan`` and ``inf`` there as 0 without a warning,
    which moves or flattens the volume.
    """
    with open(path, "rb") as file:
        head = file.read(65536)
    start = head.find(b"<ImageData")
    if start < 0:
        return  # not an image file: the reader says so
    tag = head[start : head.find(b">", start)].decode("ascii", "replace")
    for name in _GRID_ATTRIBUTES:
        match = re.search(rf'\b{name}="([^"]*)"', tag)
        if match is None:
            continue
        try:
            values = [float(word) for word in match.group(1).split()]
        except ValueError:
            raise ValueError(f"cannot read {path}: its {name} {match.group(1)!r} is not a list of numbers") from None
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"cannot read {path}: its {name} {match.group(1)!r} is not finite")


def _ply_binary_size(data: np.ndarray, elements, order: str) -> int:
    """Bytes the binary PLY ``elements`` take from the start of ``data``; more than ``len(data)`` if truncated."""
    offset = 0
    for _, count, props in elements:
        layout = [(np.dtype(order + _PLY_TYPES.get(p[1], "u1")), np.dtype(_PLY_TYPES.get(p[2], "i4")).itemsize)
                  if p[0] == "list" and len(p) >= 3 else (None, np.dtype(_PLY_TYPES.get(p[0], "f8")).itemsize)
                  for p in props]
        if all(kind is None for kind, _ in layout):
            offset += count * sum(size for _, size in layout)
            continue
        first = _ply_record(data, offset, layout)
        if count == 0 or first is None:
            return offset + (0 if count == 0 else len(data) + 1)
        size, counts, positions = first
        if offset + count * size <= len(data) and all(
                np.all(np.lib.stride_tricks.as_strided(data[offset + at:], (count, kind.itemsize), (size, 1))
                       .copy().view(kind).ravel() == n) for (kind, _), n, at in zip(
                    [entry for entry in layout if entry[0] is not None], counts, positions)):
            offset += count * size  # every record has the first one's list lengths (triangles, say)
            continue
        for _ in range(count):  # records of different sizes: one pass over their counts
            record = _ply_record(data, offset, layout)
            if record is None:
                return len(data) + 1
            offset += record[0]
    return offset


def _ply_record(data: np.ndarray, offset: int, layout) -> tuple[int, list[int], list[int]] | None:
    """Size, list lengths and list-count positions of the binary PLY record at ``offset``; None if cut off."""
    at, counts, positions = 0, [], []
    for kind, size in layout:
        if kind is None:
            at += size
            continue
        if offset + at + kind.itemsize > len(data):
            return None
        n = int(data[offset + at:offset + at + kind.itemsize].view(kind)[0])
        counts.append(n)
        positions.append(at)
        at += kind.itemsize + n * size
    return (at, counts, positions) if offset + at <= len(data) else None


def _read(path: Path) -> pv.DataObject:
    """``pv.read`` with one ``ValueError`` naming the file for empty files, unknown formats and unreadable content,
    and ``FileNotFoundError`` for a missing one.

    VTK's own error printout of a reader is switched off: the error reaches
    the caller once, as the exception.
    """
    if path.is_dir():
        raise IsADirectoryError(f"{path} is a folder, not a file")
    if not path.is_file():
        raise FileNotFoundError(f"no such file: {path}")
    if path.stat().st_size == 0:
        raise ValueError(f"{path} is empty (0 bytes)")
    if path.suffix.lower() == ".ply":
        _check_ply(path)
    elif path.suffix.lower() == ".vti":
        _check_vti(path)
    shown = vtkObject.GetGlobalWarningDisplay()
    vtkObject.GlobalWarningDisplayOff()
    try:
        data = pv.read(path)
    except (ValueError, OSError, RuntimeError, TypeError) as exc:
        raise ValueError(f"cannot read {path}: {' '.join(str(exc).split())}") from None
    finally:
        vtkObject.SetGlobalWarningDisplay(shown)
    if data is None:
        raise ValueError(f"cannot read {path}: no data in it")
    return data


def read_dataset(path: str | os.PathLike) -> pv.DataObject:
    """Read any VTK dataset PyVista reads; refuse a file that holds no points.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is empty, unreadable or damaged (VTK's XML readers then
        give an empty dataset), or holds no points.
    """
    path = Path(path)
    data = _read(path)
    if isinstance(data, pv.MultiBlock):
        empty = all(block is None or getattr(block, "n_points", 0) == 0 for block in data.recursive_iterator())
    else:
        empty = data.n_points == 0
    if empty:
        raise ValueError(f"{path} holds no points (an empty dataset, or a damaged file)")
    return data


def read_image(path: str | os.PathLike) -> pv.ImageData:
    """Read a volume on a regular grid (VTI, MHD/MHA, NRRD, ... anything PyVista reads as ImageData).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file does not hold an image.
    """
    path = Path(path)
    data = _read(path)
    if not isinstance(data, pv.ImageData):
        raise ValueError(f"{path} holds a {type(data).__name__}, not an image on a regular grid")
    return data


def read_mesh(path: str | os.PathLike) -> pv.PolyData:
    """Read a surface from any format PyVista reads (PLY, STL, OBJ, VTP, VTK, ...).

    Volumetric datasets are reduced to their outer surface.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    pyvista.PolyData

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file holds no surface.
    """
    path = Path(path)
    data = _read(path)
    if isinstance(data, pv.ImageData):
        raise ValueError(f"{path} holds an image (a volume on a regular grid), not a surface; "
                         "this stage takes a triangle mesh (PLY, STL, OBJ, VTP, VTK)")
    if isinstance(data, pv.MultiBlock):
        data = _surface_block(data, path)
    if not isinstance(data, pv.PolyData):
        data = data.extract_surface(algorithm="dataset_surface")
    if data.n_points == 0:
        raise ValueError(f"{path} holds no surface points")
    return data


def _surface_block(blocks: pv.MultiBlock, path: Path) -> pv.DataSet:
    """The one block of a MultiBlock that holds a surface (its polygons), e.g. ``surface`` of a voxel result.

    A result's blocks are not one mesh: merged, a voxel state's grid and its
    isosurface, or shards and their links, were reported as non-triangles or
    non-manifold edges. A MultiBlock of a single non-empty block is that block.
    """
    named = [(blocks.get_block_name(i) or f"block {i}", block) for i, block in enumerate(blocks)
             if block is not None and block.n_points]
    if len(named) == 1:
        block = named[0][1]
        return block.combine() if isinstance(block, pv.MultiBlock) else block
    surfaces = [(name, block) for name, block in named if isinstance(block, pv.PolyData) and block.n_cells
                and block.n_cells > block.n_verts + block.n_lines]
    if len(surfaces) == 1:
        return surfaces[0][1]
    kinds = ", ".join(f"{name} ({type(block).__name__})" for name, block in named)
    raise ValueError(f"{path} is a MultiBlock of {len(named)} blocks: {kinds or 'none with points'}; "
                     f"{'more than one' if surfaces else 'none'} holds a surface: save the block to use as its "
                     "own .vtp file")


def write_atomic(dataset: pv.DataObject, path: str | os.PathLike) -> Path:
    """Save ``dataset`` to ``path`` (format by extension) through a temporary file and a rename.

    A ``.vtm`` MultiBlock is written with its block folder named after it
    (``out.vtm`` and ``out_blocks/``, see :func:`blocks_folder`): both are
    built in a hidden temporary folder, then the folder replaces the previous
    one and the ``.vtm`` is renamed last, so no stale or orphaned blocks
    remain.

    Parameters
    ----------
    dataset : pyvista.DataObject
    path : str or path-like

    Returns
    -------
    pathlib.Path
        The written path.
    """
    path = Path(path)
    dataset = pv.wrap(dataset)
    if isinstance(dataset, pv.MultiBlock) and path.suffix.lower() == ".vtm":
        _write_multiblock(dataset, path)
        return path
    if path.suffix.lower() in SURFACE_ONLY:
        arrays = [*dataset.point_data, *dataset.cell_data, *dataset.field_data]
        if arrays:
            listed = ", ".join(arrays[:6]) + (f" and {len(arrays) - 6} more" if len(arrays) > 6 else "")
            warnings.warn(f"{path.name}: a {path.suffix.lower()} file keeps the surface only; its {len(arrays)} "
                          f"arrays ({listed}) are not written: write .vtp (or .vtk) to keep them", UserWarning,
                          stacklevel=2)
    with atomic_path(path) as tmp:
        dataset.save(tmp)
    return path


def blocks_folder(path: str | os.PathLike) -> Path:
    """The folder holding the blocks of the ``.vtm`` file ``path``: ``<stem>_blocks`` beside it.

    It differs from the ``<stem>/`` folder of a ``<stem>.pvd`` series, so a
    run's final ``.vtm`` and its time series can share a name.
    """
    path = Path(path)
    return path.with_name(f"{path.stem}_blocks")


def _write_multiblock(blocks: pv.MultiBlock, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    try:
        blocks.save(work / path.name)  # writes work/<name>.vtm and work/<stem>/ with relative references
        mode = file_mode()
        for item in work.rglob("*"):
            os.chmod(item, mode | 0o111 if item.is_dir() else mode)
        folder, built = blocks_folder(path), work / path.stem
        if built.is_dir():
            _relink(work / path.name, f"{path.stem}/", f"{folder.name}/")
            old = work / ".previous"
            if folder.is_dir():
                os.replace(folder, old)
            os.replace(built, folder)
        os.replace(work / path.name, path)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _relink(vtm: Path, old: str, new: str) -> None:
    """Point the ``file`` references of a ``.vtm`` that start with folder ``old`` to folder ``new``."""
    tree = ElementTree.parse(vtm)
    for element in tree.iter("DataSet"):
        name = element.get("file", "")
        if name.startswith(old):
            element.set("file", new + name[len(old):])
    tree.write(vtm, encoding="utf-8", xml_declaration=True)


class TimeSeriesWriter:
    """Write datasets step by step into a ``.pvd`` collection.

    Each step goes to ``<stem>/<stem>_<index>.<ext>`` and the ``.pvd`` index is
    rewritten after it, both atomically: a run interrupted at any moment
    leaves a valid collection of all steps completed so far. The steps of an
    earlier series of the same name are removed once the new index replaces
    its own (after the first step), so the folder holds the new series' steps
    only.

    Parameters
    ----------
    path : str or path-like
        The ``.pvd`` file to create (replaced if it exists).

    Examples
    --------
    >>> import pyvista as pv, tempfile, os
    >>> from pverosion.io import TimeSeriesWriter
    >>> folder = tempfile.mkdtemp()
    >>> with TimeSeriesWriter(os.path.join(folder, "run.pvd")) as series:
    ...     for step in range(3):
    ...         _ = series.write(pv.Sphere(radius=1 + step), time=step)
    >>> pv.get_reader(os.path.join(folder, "run.pvd")).time_values
    [0.0, 1.0, 2.0]
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        if self.path.suffix != ".pvd":
            raise ValueError(f"time series path must end in .pvd; got {self.path}")
        self.folder = self.path.with_suffix("")
        self.entries: list[tuple[float, str]] = []

    def write(self, dataset: pv.DataObject, time: float) -> Path:
        """Append ``dataset`` as the step at ``time`` and update the index.

        Parameters
        ----------
        dataset : pyvista.DataObject
        time : float
            Must increase from step to step.

        Returns
        -------
        pathlib.Path
            The file written for this step.
        """
        dataset = pv.wrap(dataset)
        time = float(time)
        if self.entries and time <= self.entries[-1][0]:
            raise ValueError(f"time values must increase; got {time} after {self.entries[-1][0]}")
        ext = EXTENSIONS.get(type(dataset).__name__)
        if ext is None:
            raise TypeError(f"cannot write {type(dataset).__name__} to a .pvd series")
        name = f"{self.folder.name}_{len(self.entries):06d}{ext}"
        target = write_atomic(dataset, self.folder / name)
        self.entries.append((time, f"{self.folder.name}/{name}"))
        self._write_index()
        if len(self.entries) == 1:
            self._remove_earlier_steps(keep=target)
        return target

    def _remove_earlier_steps(self, *, keep: Path) -> None:
        """Remove the step files (and blocks folders) of an earlier series in the folder, but ``keep``."""
        step = re.compile(rf"{re.escape(self.folder.name)}_\d{{6}}(\.\w+|_blocks)")
        kept = {keep.name, blocks_folder(keep).name}
        for item in self.folder.iterdir():
            if step.fullmatch(item.name) and item.name not in kept:
                if item.is_dir():
                    shutil.rmtree(item, ignore_errors=True)
                else:
                    item.unlink(missing_ok=True)

    def _write_index(self) -> None:
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                 "  <Collection>"]
        lines += [f'    <DataSet timestep="{t!r}" group="" part="0" file={quoteattr(f)}/>' for t, f in self.entries]
        lines += ["  </Collection>", "</VTKFile>", ""]
        with atomic_path(self.path) as tmp:
            tmp.write_text("\n".join(lines), encoding="utf-8")

    def __enter__(self) -> TimeSeriesWriter:
        return self

    def __exit__(self, *exc) -> None:
        return None
