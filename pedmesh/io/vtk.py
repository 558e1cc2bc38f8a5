"""VTK output that ParaView opens: ``.vtu`` meshes (meshio; the frames of a time series and
a run's per-cell maps through VTK's own writer, LZ4-compressed, so that a run does not
import meshio), ``.vtp`` point clouds (VTK's writer, the bytes pyvista writes) and ``.pvd``
time-series collections.

2-D vector fields, shape (n, 2), are written with a zero third component so that ParaView
can draw them as glyphs. pyvista reads PVD but does not write it, so the small PVD writer
is ours; it rewrites the index after every frame, so an interrupted run leaves a valid
collection of the frames written so far.

Every file is written to a temporary ``.part`` file first and renamed when complete; a
write that fails (a full disk) removes its ``.part`` file and raises :class:`OSError`
naming the file.
"""

from __future__ import annotations

import errno
import os
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Mapping

import numpy as np

from ..errors import PedmeshError
from .files import write_through_part

__all__ = ["FrameReadError", "frame_intact", "check_frames_whole", "frame_density",
           "check_same_mesh", "mesh_to_meshio", "write_vtu", "write_cells_vtu", "write_vtp",
           "PVDWriter", "read_pvd_index", "read_vtu", "read_vtp"]

ArrayMap = Mapping[str, np.ndarray] | None


def _pad3(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    if a.ndim == 2 and a.shape[1] == 2:
        return np.column_stack([a, np.zeros(len(a), dtype=a.dtype)])
    return a


def mesh_to_meshio(mesh, point_data: ArrayMap = None, cell_data: ArrayMap = None, *,
                   boundary: bool = False):
    """A :class:`meshio.Mesh` of a :class:`~pedmesh.mesh.TriMesh` (z = 0) or of a
    building's :class:`~pedmesh.mesh.surface.SurfaceMesh` (in 3-D; without ``boundary``).

    Parameters
    ----------
    mesh
        The triangle mesh.
    point_data, cell_data
        Fields per vertex (n, ...) and per triangle (m, ...).
    boundary
        Also write the boundary edges as line cells with the cell fields ``boundary_kind``
        (1 wall, 2 obstacle, 3 exit) and ``boundary_owner`` (obstacle / exit number);
        triangles get 0 and -1 there, and ``cell_data`` fields get NaN (or -1) on lines.
    """
    import meshio

    pts = mesh.points if mesh.points.shape[1] == 3 else \
        np.column_stack([mesh.points, np.zeros(mesh.n_points)])  # (a building is 3-D)
    cells = [("triangle", np.asarray(mesh.triangles))]
    cd = {k: [_pad3(v)] for k, v in (cell_data or {}).items()}
    for k, v in (cell_data or {}).items():
        if len(v) != mesh.n_triangles:
            raise ValueError(f"cell field '{k}' has {len(v)} values for {mesh.n_triangles} "
                             "triangles")
    for k, v in (point_data or {}).items():
        if len(v) != mesh.n_points:
            raise ValueError(f"point field '{k}' has {len(v)} values for {mesh.n_points} vertices")
    if boundary:
        b = mesh.boundary_edges
        cells.append(("line", np.asarray(mesh.edges[b])))
        for k, v in list(cd.items()):
            arr = v[0]
            fill = np.nan if np.issubdtype(arr.dtype, np.floating) else -1
            pad = np.full((len(b),) + arr.shape[1:], fill, dtype=arr.dtype)
            cd[k] = [arr, pad]
        cd["boundary_kind"] = [np.zeros(mesh.n_triangles, np.int32),
                               np.asarray(mesh.edge_kind[b], np.int32)]
        cd["boundary_owner"] = [np.full(mesh.n_triangles, -1, np.int32),
                                np.asarray(mesh.edge_owner[b], np.int32)]
    pd = {k: _pad3(v) for k, v in (point_data or {}).items()}
    return meshio.Mesh(pts, cells, point_data=pd, cell_data=cd)


def write_vtu(path: str | Path, mesh, point_data: ArrayMap = None, cell_data: ArrayMap = None,
              *, boundary: bool = False) -> Path:
    """Write a mesh with fields to a ``.vtu`` file (see :func:`mesh_to_meshio`)."""
    m = mesh_to_meshio(mesh, point_data, cell_data, boundary=boundary)
    return write_through_part(path, lambda tmp: m.write(tmp, file_format="vtu"))


def _grid(mesh):
    """A VTK unstructured grid of the mesh's triangles (z = 0; a building's in 3-D), built
    with VTK's own classes (pyvista would add a quarter of a second of imports to every
    run)."""
    from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import VTK_TRIANGLE, vtkCellArray, vtkUnstructuredGrid

    pts = vtkPoints()
    xyz = mesh.points if mesh.points.shape[1] == 3 else \
        np.column_stack([mesh.points, np.zeros(mesh.n_points)])  # (a building is 3-D)
    pts.SetData(numpy_to_vtk(np.ascontiguousarray(xyz), deep=True))
    m = mesh.n_triangles
    offsets = numpy_to_vtkIdTypeArray(np.arange(0, 3 * m + 1, 3, dtype=np.int64), deep=True)
    conn = numpy_to_vtkIdTypeArray(np.ascontiguousarray(mesh.triangles, np.int64).ravel(),
                                   deep=True)
    cells = vtkCellArray()
    cells.SetData(offsets, conn)
    grid = vtkUnstructuredGrid()
    grid.SetPoints(pts)
    grid.SetCells(VTK_TRIANGLE, cells)
    return grid


def _vtk_array(name: str, values: np.ndarray):
    from vtkmodules.util.numpy_support import numpy_to_vtk

    arr = numpy_to_vtk(np.ascontiguousarray(_pad3(np.asarray(values))), deep=True)
    arr.SetName(name)
    return arr


def write_cells_vtu(path: str | Path, mesh, cell_data: ArrayMap) -> Path:
    """Write a triangle mesh (``points`` (n, 2 or 3) [m], ``triangles`` (m, 3),
    ``n_points``, ``n_triangles``) with per-triangle fields to a ``.vtu`` by VTK's own
    writer, as the density frames are written (no meshio import in a run); through
    ``<name>.part``, renamed when complete."""
    path = Path(path)
    return _write_frame(path, _grid(mesh), mesh, None, cell_data,
                        tmp=path.with_name(path.name + ".part"))


def _write_frame(path: Path, grid, mesh, point_data: ArrayMap, cell_data: ArrayMap,
                 tmp: Path | None = None) -> Path:
    """Write ``grid`` with these fields (replacing the previous frame's) to ``path`` with
    VTK's XML writer: appended raw data, LZ4-compressed; through ``tmp`` (default
    ``<stem>.part.vtu``)."""
    from vtkmodules.vtkIOCore import vtkLZ4DataCompressor
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridWriter

    for k, v in (point_data or {}).items():
        if len(v) != mesh.n_points:
            raise ValueError(f"point field '{k}' has {len(v)} values for {mesh.n_points} vertices")
    for k, v in (cell_data or {}).items():
        if len(v) != mesh.n_triangles:
            raise ValueError(f"cell field '{k}' has {len(v)} values for {mesh.n_triangles} "
                             "triangles")
    pd, cd = grid.GetPointData(), grid.GetCellData()
    pd.Initialize()
    cd.Initialize()
    for k, v in (point_data or {}).items():
        pd.AddArray(_vtk_array(k, v))
    for k, v in (cell_data or {}).items():
        cd.AddArray(_vtk_array(k, v))
    if tmp is None:
        tmp = path.with_name(path.stem + ".part.vtu")
    w = vtkXMLUnstructuredGridWriter()
    w.SetFileName(str(tmp))
    w.SetInputData(grid)
    w.SetDataModeToAppended()
    w.EncodeAppendedDataOff()
    w.SetCompressor(vtkLZ4DataCompressor())
    return _vtk_write_through(w, path, tmp)


def _vtk_write_through(writer, path: Path, tmp: Path) -> Path:
    """Run a VTK writer set to write ``tmp`` (:func:`_vtk_write`), then rename ``tmp`` to
    ``path``; a failure removes ``tmp``."""
    try:
        _vtk_write(writer, path)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def _vtk_write(writer, path: Path) -> None:
    """Run a VTK writer without VTK's messages on the console; a failure is an OSError
    naming ``path`` (ENOSPC when VTK says the disk is full)."""
    from vtkmodules.vtkCommonCore import vtkObject
    from vtkmodules.vtkCommonMisc import vtkErrorCode

    shown = vtkObject.GetGlobalWarningDisplay()
    vtkObject.GlobalWarningDisplayOff()
    try:
        ok = writer.Write()
    finally:
        vtkObject.SetGlobalWarningDisplay(shown)
    code = writer.GetErrorCode()
    if ok and code == vtkErrorCode.NoError:
        return
    if code == vtkErrorCode.OutOfDiskSpaceError:
        raise OSError(errno.ENOSPC, "out of disk space (or over the file size limit)",
                      str(path))
    raise OSError(errno.EIO, f"VTK could not write it "
                  f"({vtkErrorCode.GetStringFromErrorCode(code) or 'unknown error'})",
                  str(path))


def _cloud(pts: np.ndarray, point_data: ArrayMap):
    """A VTK point cloud (one vertex cell per point) of ``pts`` (n, 3) with these fields,
    built with VTK's own classes as pyvista's ``PolyData(pts)`` with ``point_data[k] =
    v`` builds it (the first field the active scalars; an empty cloud keeps every field's
    name, type and components, with no rows): the same file, without pyvista's objects and
    imports."""
    from vtkmodules.util.numpy_support import (
        get_vtk_array_type,
        numpy_to_vtk,
        numpy_to_vtkIdTypeArray,
    )
    from vtkmodules.vtkCommonCore import vtkDataArray, vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData

    n = len(pts)
    vtk_pts = vtkPoints()
    vtk_pts.SetData(numpy_to_vtk(np.ascontiguousarray(pts), deep=True))
    cloud = vtkPolyData()
    cloud.SetPoints(vtk_pts)
    verts = vtkCellArray()
    if n:  # offsets and connectivity as Int64 arrays (pyvista's legacy-format verts)
        verts.SetData(numpy_to_vtk(np.arange(n + 1, dtype=np.int64), deep=True),
                      numpy_to_vtk(np.arange(n, dtype=np.int64), deep=True))
    else:  # (pyvista's empty cloud: fixed-size storage of no vertices)
        verts.SetData(1, numpy_to_vtkIdTypeArray(np.zeros(0, np.int64), deep=True))
    cloud.SetVerts(verts)
    pd = cloud.GetPointData()
    for k, v in (point_data or {}).items():
        v = np.asarray(_pad3(v))
        if n:
            arr = numpy_to_vtk(np.ascontiguousarray(v), deep=True)
        else:
            arr = vtkDataArray.CreateDataArray(get_vtk_array_type(v.dtype))
            arr.SetNumberOfComponents(int(np.prod(np.shape(v)[1:], dtype=np.int64)) or 1)
            arr.SetNumberOfTuples(0)
        arr.SetName(k)
        pd.AddArray(arr)
        if n and pd.GetScalars() is None:
            pd.SetActiveScalars(k)
    return cloud


def write_vtp(path: str | Path, points: np.ndarray, point_data: ArrayMap = None) -> Path:
    """Write a point cloud [m] (n, 2) at z = 0, or (n, 3) in 3-D (a building's), with
    per-point fields to a ``.vtp`` file (VTK's XML writer, zlib-compressed binary; the
    bytes pyvista's ``save(binary=True)`` writes)."""
    pts = np.asarray(points, dtype=float)
    pts = pts.reshape(-1, 3) if pts.ndim == 2 and pts.shape[1] == 3 else pts.reshape(-1, 2)
    if pts.shape[1] == 2:
        pts = np.column_stack([pts, np.zeros(len(pts))])
    cloud = _cloud(pts, point_data)
    path = Path(path)
    tmp = path.with_name(path.stem + ".part.vtp")
    # VTK's XML writer as pyvista's save(binary=True) sets it up (the same bytes), run
    # here so that a failed write is seen
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

    w = vtkXMLPolyDataWriter()
    w.SetFileName(str(tmp))
    w.SetInputData(cloud)
    w.SetDataModeToBinary()
    w.SetCompressorTypeToZLib()
    return _vtk_write_through(w, path, tmp)


class PVDWriter:
    """Write a time series as a ParaView ``.pvd`` collection.

    Frames go to ``<stem>/<stem>_<frame>.vtu`` (or ``.vtp``) next to the ``.pvd`` file.

    Examples
    --------
    >>> with PVDWriter("out/density.pvd") as w:              # doctest: +SKIP
    ...     for t, rho in frames:
    ...         w.write_mesh(t, mesh, cell_data={"rho": rho})
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if self.path.suffix.lower() != ".pvd":
            raise ValueError(f"a PVD collection needs a .pvd suffix, got {self.path}")
        self.dir = self.path.with_suffix("")
        self.dir.mkdir(parents=True, exist_ok=True)
        self.entries: list[tuple[float, str]] = []
        self._grid = self._grid_mesh = None  # the VTK grid of the frames' mesh
        self._lines: list[str] = []  # the index's DataSet lines
        self._write_index()

    def __enter__(self) -> "PVDWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def n_frames(self) -> int:
        return len(self.entries)

    def _frame_path(self, ext: str) -> Path:
        return self.dir / f"{self.dir.name}_{len(self.entries):06d}{ext}"

    def write_mesh(self, t: float, mesh, point_data: ArrayMap = None,
                   cell_data: ArrayMap = None) -> Path:
        """Add a mesh frame at time ``t`` [s]: a ``.vtu`` written by VTK's own XML writer
        from a grid kept for the mesh (only the fields change between frames), its arrays
        LZ4-compressed (ParaView reads it; ten times faster to write than meshio's zlib,
        files about as large)."""
        if self._grid is None or self._grid_mesh is not mesh:
            self._grid, self._grid_mesh = _grid(mesh), mesh
        p = _write_frame(self._frame_path(".vtu"), self._grid, mesh, point_data, cell_data)
        return self.add_file(t, p)

    def write_points(self, t: float, points: np.ndarray, point_data: ArrayMap = None) -> Path:
        """Add a point-cloud frame at time ``t`` [s]."""
        p = write_vtp(self._frame_path(".vtp"), points, point_data)
        return self.add_file(t, p)

    def add_file(self, t: float, file: str | Path) -> Path:
        """Register an already written dataset file as the frame at time ``t`` [s]."""
        rel = os.path.relpath(Path(file), self.path.parent)
        self.entries.append((float(t), Path(rel).as_posix()))
        self._write_index()
        return Path(file)

    def _write_index(self) -> None:
        """The collection file, rewritten whole after every frame (an interrupted run keeps
        a valid one); the frames' lines are kept, so a frame adds one line of work."""
        while len(self._lines) < len(self.entries):
            t, f = self.entries[len(self._lines)]
            self._lines.append(f'    <DataSet timestep="{t!r}" group="" part="0" '
                               f'file={_quoteattr(f)} />\n')
        text = ("<?xml version='1.0' encoding='utf-8'?>\n"
                '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n'
                "  <Collection>\n" + "".join(self._lines) + "  </Collection>\n</VTKFile>\n")
        tmp = self.path.with_name(self.path.name + ".part")
        try:
            tmp.write_text(text, encoding="utf-8")
            os.replace(tmp, self.path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise

    def close(self) -> None:
        self._write_index()


def _quoteattr(data: str) -> str:
    """``data`` escaped and quoted as an XML attribute value, exactly as
    ``xml.sax.saxutils.quoteattr`` does it (whose module imports urllib.request, http.client
    and ssl: a hundredth of a second at every run's first frame)."""
    data = data.replace("&", "&amp;").replace(">", "&gt;").replace("<", "&lt;")
    data = data.replace("\n", "&#10;").replace("\r", "&#13;").replace("\t", "&#9;")
    if '"' not in data:
        return f'"{data}"'
    if "'" not in data:
        return f"'{data}'"
    return '"' + data.replace('"', "&quot;") + '"'


class FrameReadError(PedmeshError, OSError):
    """A frame (``.vtu``, ``.vtp``) or index (``.pvd``) of a run folder is missing or
    cannot be read; the message names the file and what is wrong with it."""


def _read_xml(reader_class, path):
    """The output of a VTK XML reader of ``path``, VTK's own error printing silenced (its
    errors become one :class:`FrameReadError` naming the file)."""
    from vtkmodules.vtkCommonCore import vtkCommand, vtkObject

    path = Path(path)
    check_frames_whole([path])
    errors: list[str] = []
    r = reader_class()
    r.AddObserver(vtkCommand.ErrorEvent, lambda obj, ev: errors.append(ev))
    shown = vtkObject.GetGlobalWarningDisplay()
    vtkObject.GlobalWarningDisplayOff()  # (the XML parser reports on objects of its own)
    try:
        r.SetFileName(str(path))
        r.Update()
        ok = not errors and r.GetErrorCode() == 0
    finally:
        vtkObject.SetGlobalWarningDisplay(shown)
    g = r.GetOutput()
    if not ok or g is None:
        raise FrameReadError(_unreadable(path))
    return g


def frame_intact(path: str | Path) -> bool:
    """Whether the VTK XML file ``path`` is there and complete (it ends with its closing
    ``</VTKFile>``: a file cut short or of another kind does not); reads its last bytes
    only."""
    try:
        with open(path, "rb") as f:
            f.seek(0, os.SEEK_END)
            f.seek(max(0, f.tell() - 256))
            return b"</VTKFile>" in f.read()
    except OSError:
        return False


def check_frames_whole(paths) -> None:
    """A :class:`FrameReadError` naming the first of ``paths`` (frames a run's index
    lists) that is missing or not whole (:func:`frame_intact`); reads their last bytes
    only."""
    for path in map(Path, paths):
        if not path.is_file():
            raise FrameReadError(f"{path}: missing (the run's index lists it)")
        if not frame_intact(path):
            raise FrameReadError(_unreadable(path))


def frame_density(path, point_data: Mapping, cell_data: Mapping,
                  triangles: np.ndarray) -> np.ndarray:
    """Cell density [ped/m^2] of the density frame read from ``path``: its cell field
    ``rho`` (a continuum model's), else a cell field ``density``, else its vertex field
    ``density`` (a particle model's) averaged over ``triangles``; a
    :class:`FrameReadError` naming ``path`` if it has none."""
    if "rho" in cell_data:
        return np.asarray(cell_data["rho"], float)
    if "density" in cell_data:
        return np.asarray(cell_data["density"], float)
    if "density" in point_data:
        return np.asarray(point_data["density"], float)[triangles].mean(axis=1)
    raise FrameReadError(f"{path}: no density field ('rho' or 'density'): not a density "
                         "frame of a pedmesh run")


def check_same_mesh(path, points: np.ndarray, triangles: np.ndarray, n_points: int,
                    own: np.ndarray) -> None:
    """A :class:`FrameReadError` naming the frame read from ``path`` unless its mesh
    (``points``, ``triangles``) is the run's first frame's (``n_points`` points, triangles
    ``own``)."""
    if len(points) != n_points or not np.array_equal(triangles, own):
        raise FrameReadError(f"{path}: a frame of another mesh ({len(points)} points, "
                             f"{len(triangles)} triangles; the run's first frame has "
                             f"{n_points} and {len(own)}, other triangles)")


def _unreadable(path: Path) -> str:
    return (f"{path}: cannot be read ({Path(path).stat().st_size} bytes: cut short or not a "
            "VTK XML file); rerun the run, or remove the frame's line from its .pvd")


def read_pvd_index(path: str | Path) -> list[tuple[float, Path]]:
    """(time, absolute file path) of every frame listed in a ``.pvd`` file."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except FileNotFoundError:
        raise FrameReadError(f"{path}: missing") from None
    except (OSError, ET.ParseError) as exc:
        raise FrameReadError(f"{path}: cannot be read as a ParaView index ({exc})") from None
    out = []
    for k, ds in enumerate(root.iter("DataSet")):
        try:
            out.append((float(ds.get("timestep")), path.parent / ds.get("file")))
        except (TypeError, ValueError):
            raise FrameReadError(f"{path}: its DataSet {k} has no valid timestep and "
                                 "file") from None
    return out


def _arrays(data, names) -> dict[str, np.ndarray]:
    from vtkmodules.util.numpy_support import vtk_to_numpy

    out = {}
    for k in range(data.GetNumberOfArrays()):
        arr = data.GetArray(k)
        if arr is not None and (names is None or arr.GetName() in names):
            out[arr.GetName()] = vtk_to_numpy(arr).copy()
    return out


def read_vtu(path: str | Path, *, point_arrays=None, cell_arrays=None):
    """(points (n, 3) [m], triangles (m, 3), point fields, cell fields) of a ``.vtu`` of
    triangles (a frame of density.pvd), read with VTK's XML reader; ``point_arrays`` and
    ``cell_arrays``: the names of the fields to return (None: all)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

    g = _read_xml(vtkXMLUnstructuredGridReader, path)
    if g.GetPoints() is None:
        raise FrameReadError(_unreadable(path))
    pts = vtk_to_numpy(g.GetPoints().GetData()).copy()
    cells = g.GetCells()
    conn = vtk_to_numpy(cells.GetConnectivityArray())
    offsets = vtk_to_numpy(cells.GetOffsetsArray())
    if len(offsets) > 1 and not np.all(np.diff(offsets) == 3):
        raise FrameReadError(f"{path}: not a mesh of triangles only (not a pedmesh frame)")
    tri = conn.reshape(-1, 3).astype(np.int64)
    return (pts, tri, _arrays(g.GetPointData(), point_arrays),
            _arrays(g.GetCellData(), cell_arrays))


def read_vtp(path: str | Path, *, arrays=None):
    """(points (n, 3) [m], point fields) of a ``.vtp`` point cloud (a frame of
    pedestrians.pvd); ``arrays``: the names of the fields to return (None: all)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

    g = _read_xml(vtkXMLPolyDataReader, path)
    p = g.GetPoints()
    if p is None:  # (an empty frame has its points, none of them)
        raise FrameReadError(_unreadable(path))
    pts = vtk_to_numpy(p.GetData()).copy()
    return pts, _arrays(g.GetPointData(), arrays)
