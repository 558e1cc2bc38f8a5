"""VTU and PVD output round-trips through meshio and pyvista."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

from pedmesh.io import PVDWriter, read_pvd_index, write_vtu
from pedmesh.mesh import triangulate


@pytest.fixture(scope="module")
def mesh(load_shipped):
    return triangulate(load_shipped("pillar_hall.json"), max_area=2.0)


def test_vtu_round_trip_meshio(mesh, tmp_path):
    rng = np.random.default_rng(0)
    rho = rng.random(mesh.n_triangles)
    phi = rng.random(mesh.n_points)
    vel = rng.random((mesh.n_points, 2))
    p = write_vtu(tmp_path / "m.vtu", mesh, point_data={"phi": phi, "velocity": vel},
                  cell_data={"rho": rho})
    m = meshio.read(p)
    np.testing.assert_array_equal(m.points[:, :2], mesh.points)
    np.testing.assert_array_equal(m.cells_dict["triangle"], mesh.triangles)
    np.testing.assert_array_equal(m.point_data["phi"], phi)
    np.testing.assert_array_equal(m.point_data["velocity"][:, :2], vel)
    assert np.all(m.point_data["velocity"][:, 2] == 0)
    np.testing.assert_array_equal(m.cell_data["rho"][0], rho)


def test_vtu_boundary_tags(mesh, tmp_path):
    p = write_vtu(tmp_path / "b.vtu", mesh, cell_data={"area": mesh.areas}, boundary=True)
    m = meshio.read(p)
    lines = m.cells_dict["line"]
    kinds = m.cell_data_dict["boundary_kind"]["line"]
    owners = m.cell_data_dict["boundary_owner"]["line"]
    b = mesh.boundary_edges
    np.testing.assert_array_equal(lines, mesh.edges[b])
    np.testing.assert_array_equal(kinds, mesh.edge_kind[b])
    np.testing.assert_array_equal(owners, mesh.edge_owner[b])
    assert np.all(np.isnan(m.cell_data_dict["area"]["line"]))


def test_vtu_round_trip_pyvista(mesh, tmp_path):
    import pyvista as pv

    rho = np.arange(mesh.n_triangles, dtype=float)
    p = write_vtu(tmp_path / "m.vtu", mesh, cell_data={"rho": rho})
    g = pv.read(p)
    assert g.n_cells == mesh.n_triangles and g.n_points == mesh.n_points
    np.testing.assert_array_equal(g.cell_data["rho"], rho)


def test_pvd_series_round_trip(mesh, tmp_path):
    import pyvista as pv

    times = [0.0, 0.5, 1.25]
    with PVDWriter(tmp_path / "density.pvd") as w:
        for k, t in enumerate(times):
            w.write_mesh(t, mesh, cell_data={"rho": np.full(mesh.n_triangles, float(k))})
    with PVDWriter(tmp_path / "peds.pvd") as w:
        for k, t in enumerate(times):
            pts = np.column_stack([np.arange(k + 1.0), np.ones(k + 1)])
            w.write_points(t, pts, {"speed": np.full(k + 1, t), "velocity": np.ones((k + 1, 2))})
    idx = read_pvd_index(tmp_path / "density.pvd")
    assert [t for t, _ in idx] == times
    assert all(f.exists() for _, f in idx)
    reader = pv.PVDReader(tmp_path / "density.pvd")
    assert list(reader.time_values) == times
    for k, t in enumerate(times):
        reader.set_active_time_value(t)
        block = reader.read()[0]
        assert np.all(block.cell_data["rho"] == k)
    reader = pv.PVDReader(tmp_path / "peds.pvd")
    reader.set_active_time_value(1.25)
    cloud = reader.read()[0]
    assert cloud.n_points == 3
    np.testing.assert_array_equal(cloud.point_data["speed"], [1.25] * 3)
    # frames are also readable one by one, and are LZ4-compressed (fast to write)
    m = pv.read(idx[2][1])
    assert np.all(m.cell_data["rho"] == 2.0)
    assert b'compressor="vtkLZ4DataCompressor"' in idx[2][1].read_bytes()[:2000]


def test_pvd_index_valid_after_each_frame(mesh, tmp_path):
    """An interrupted run keeps a readable collection of the frames written so far."""
    w = PVDWriter(tmp_path / "s.pvd")
    w.write_mesh(0.0, mesh, cell_data={"rho": np.zeros(mesh.n_triangles)})
    w.write_mesh(1.0, mesh, cell_data={"rho": np.ones(mesh.n_triangles)})
    # no close(): the index on disk already lists both frames
    assert [t for t, _ in read_pvd_index(tmp_path / "s.pvd")] == [0.0, 1.0]


def test_field_length_is_checked(mesh, tmp_path):
    with pytest.raises(ValueError, match="cell field 'rho'"):
        write_vtu(tmp_path / "x.vtu", mesh, cell_data={"rho": np.zeros(3)})
    with pytest.raises(ValueError, match="point field 'phi'"):
        PVDWriter(tmp_path / "s.pvd").write_mesh(0.0, mesh, point_data={"phi": np.zeros(3)})


def test_empty_point_frame_keeps_its_arrays(tmp_path):
    """The last pedestrians frame (everyone out) has the same arrays as the others, with
    no rows, so that ParaView's filters find them in every frame."""
    import pyvista as pv

    from pedmesh.io.vtk import write_vtp

    data = {"id": np.arange(3, dtype=np.int64), "velocity": np.ones((3, 2)),
            "speed": np.ones(3), "density": np.full(3, 2.0)}
    full = pv.read(write_vtp(tmp_path / "full.vtp", np.zeros((3, 2)), data))
    empty = pv.read(write_vtp(tmp_path / "empty.vtp", np.zeros((0, 2)),
                              {k: v[:0] for k, v in data.items()}))
    assert empty.n_points == 0
    assert set(empty.point_data.keys()) == set(full.point_data.keys()) == set(data)
    for k in data:
        assert empty.point_data[k].shape[1:] == full.point_data[k].shape[1:]
        assert empty.point_data[k].dtype == full.point_data[k].dtype
