"""Open a pedmesh run in ParaView and render it: the density, and the pedestrians as
spheres coloured by speed. The ParaView steps of docs/running.md are these, done by hand.

    xvfb-run -a pvbatch docs/paraview_check.py RUN_DIR OUT.png [--time T]
    xvfb-run -a pvbatch docs/paraview_check.py --mesh MESH.vtu OUT.png

RUN_DIR is a ``pedmesh run`` folder; the frame nearest T [s] is shown (default: the middle
of the run). A building's run (frames in 3-D) is shown from the front and above, its
heights stretched (``Transform``, z x 3) so that every level shows between the others.
With ``--mesh`` it shows a mesh written by ``pedmesh mesh -o MESH.vtu`` and its exits,
picked out of the boundary line cells with a Threshold on ``boundary_kind`` (1 wall, 2
obstacle, 3 exit). Prints what it rendered; exits non-zero with a message if
something it needs is missing.
"""

import os
import sys

from paraview.simple import (  # noqa: F401 (pvbatch provides paraview.simple)
    ColorBy,
    GetActiveViewOrCreate,
    GetAnimationScene,
    Glyph,
    Transform,
    OpenDataFile,
    Render,
    ResetCamera,
    SaveScreenshot,
    Show,
    Threshold,
)


#: the stretch of a building's heights in the picture (levels apart)
Z_STRETCH = 3.0


def fail(msg):
    print(f"paraview_check: {msg}", file=sys.stderr)
    sys.exit(2)


def ranges(source, association, name, t=None):
    source.UpdatePipeline() if t is None else source.UpdatePipeline(t)
    info = source.GetDataInformation()
    data = info.GetPointDataInformation() if association == "POINTS" \
        else info.GetCellDataInformation()
    arr = data.GetArrayInformation(name)
    if arr is None:
        return None
    return arr.GetComponentRange(-1 if arr.GetNumberOfComponents() > 1 else 0)


def show_mesh(path, png):
    mesh = OpenDataFile(path)
    if mesh is None:
        fail(f"{path}: ParaView cannot open it")
    view = GetActiveViewOrCreate("RenderView")
    Show(mesh, view)
    if ranges(mesh, "CELLS", "boundary_kind") is None:
        fail(f"{path}: no cell array 'boundary_kind' (write it with pedmesh mesh -o)")
    exits = Threshold(Input=mesh)
    exits.Scalars = ["CELLS", "boundary_kind"]
    exits.LowerThreshold = 3
    exits.UpperThreshold = 3
    exits.UpdatePipeline()
    n_exit = exits.GetDataInformation().GetNumberOfCells()
    d = Show(exits, view)
    d.AmbientColor = d.DiffuseColor = [0.0, 0.7, 0.0]
    d.LineWidth = 4.0
    view.ViewSize = [1000, 600]
    ResetCamera(view)
    Render(view)
    SaveScreenshot(png, view)
    print(f"mesh: {mesh.GetDataInformation().GetNumberOfCells()} cells, "
          f"{n_exit} exit edges")


def show_run(run, png, when):
    dens_file = os.path.join(run, "density.pvd")
    if not os.path.exists(dens_file):
        fail(f"{run}: no density.pvd (not a pedmesh run folder?)")
    density = OpenDataFile(dens_file)
    times = list(density.TimestepValues) if density.TimestepValues else [0.0]
    density.UpdatePipeline(times[0])
    bounds = density.GetDataInformation().GetBounds()
    building = bounds[5] - bounds[4] > 1e-6  # frames in 3-D: levels at their heights
    raw = density
    if building:
        density = Transform(Input=raw)
        density.Transform.Scale = [1.0, 1.0, Z_STRETCH]
    t = min(times, key=lambda x: abs(x - (when if when is not None else times[-1] / 2)))
    scene = GetAnimationScene()
    scene.UpdateAnimationUsingDataTimeSteps()
    scene.AnimationTime = t
    view = GetActiveViewOrCreate("RenderView")
    view.ViewTime = t
    d = Show(density, view)
    # continuum runs: cell data rho; social force runs: vertex data density
    if ranges(raw, "CELLS", "rho", t) is not None:
        field = ("CELLS", "rho")
    elif ranges(raw, "POINTS", "density", t) is not None:
        field = ("POINTS", "density")
    else:
        fail(f"{dens_file}: neither cell data 'rho' nor point data 'density'")
    ColorBy(d, field)
    lo, hi = ranges(raw, *field, t)
    d.RescaleTransferFunctionToDataRange(True, False)
    d.SetScalarBarVisibility(view, True)
    line = f"t = {t:g} s: {field[1]} in [{lo:.3g}, {hi:.3g}] ped/m^2"
    peds_file = os.path.join(run, "pedestrians.pvd")
    if os.path.exists(peds_file):
        peds = OpenDataFile(peds_file)
        peds.UpdatePipeline(t)
        n = peds.GetDataInformation().GetNumberOfPoints()
        if ranges(peds, "POINTS", "speed") is None:
            fail(f"{peds_file}: no point array 'speed' at t = {t:g} s")
        if building:
            peds = Transform(Input=peds)
            peds.Transform.Scale = [1.0, 1.0, Z_STRETCH]
        g = Glyph(Input=peds, GlyphType="Sphere")
        g.ScaleArray = ["POINTS", "No scale array"]
        g.ScaleFactor = 0.3  # a body is about 0.3 m wide
        g.GlyphMode = "All Points"
        gd = Show(g, view)
        ColorBy(gd, ("POINTS", "speed"))
        gd.SetScalarBarVisibility(view, True)
        line += f"; {n} pedestrians"
    view.ViewSize = [1000, 600]
    ResetCamera(view)
    if building:  # from the front and above, a little from the side
        cam = view.GetActiveCamera()
        cam.Elevation(-62.0)
        cam.Azimuth(-25.0)
        cam.OrthogonalizeViewUp()
        ResetCamera(view)
        line += (f"; a building of height {bounds[5] - bounds[4]:g} m, seen from the front "
                 f"(heights x {Z_STRETCH:g})")
    Render(view)
    SaveScreenshot(png, view)
    print(line)


def main(argv):
    if len(argv) >= 3 and argv[0] == "--mesh":
        show_mesh(argv[1], argv[2])
        return
    if len(argv) < 2:
        fail(__doc__.strip().splitlines()[3].strip())
    when = None
    if "--time" in argv:
        when = float(argv[argv.index("--time") + 1])
    show_run(argv[0], argv[1], when)


main(sys.argv[1:])
