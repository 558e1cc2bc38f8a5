"""What the second core buys: the continuum kernels on 1 and on 2 numba threads.

A continuum run (default eos on the 100,000-person venue, 65,000 cells) is advanced to a
state with a crowd in motion; then each hot kernel of a step, and the whole step, is timed
on 1 and 2 threads, the two alternating (A, B, A, B, ...) so that the shared machine's
noise hits both alike. Printed per kernel: median and best time per call on each thread
count and the speed-up (median over median, best over best). The kernels are those of
``FVSolver.residual`` and of the implicit correction: the reconstruction, the high- and
first-order fluxes, the flux limiter with the divergence, the relaxation source, and the
implicit correction (whose conjugate gradients run in scipy, serially).

    python benchmarks/threads.py [--room geometries/venue.json] [--model eos]
                                 [--warm 60] [--repeats 15]

Results are bitwise the same on any thread count (tests/continuum/test_parallel.py); this
script measures only the time.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np
from pedmesh.mesh import triangulate

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    import numba

    from pedmesh.io import load_room
    from pedmesh.models import get_model

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--room", default=str(ROOT / "geometries" / "venue.json"))
    ap.add_argument("--model", default="eos")
    ap.add_argument("--warm", type=float, default=60.0,
                    help="simulated seconds before timing (default 60)")
    ap.add_argument("--repeats", type=int, default=15)
    args = ap.parse_args(argv)
    if numba.config.NUMBA_NUM_THREADS < 2:
        raise SystemExit("needs NUMBA_NUM_THREADS >= 2")
    room = load_room(args.room)
    mesh = triangulate(room)
    run = get_model(args.model).build(room, mesh, {"threads": 2})
    t0 = time.perf_counter()
    while run.t < args.warm and not run.done:
        run.step()
    s = run.solver
    Q, t = run.state.Q, run.t
    print(f"{args.model} on {Path(args.room).name}: {mesh.n_triangles} cells, "
          f"{s.n_active} active, {run.remaining:.0f} people inside at t = {t:.1f} s "
          f"(warm-up {time.perf_counter() - t0:.0f} s)")
    dt = s.max_dt(Q, t)
    s._buffers(Q.shape[1])
    nv = Q.shape[1]
    Es, Vi = s._Es.reshape(-1, nv), s._Vi
    opt = s.options

    def recon():
        s.recon.apply(Q, Es, Vi, order=opt.order, eps_hat=opt.eps_hat, qref=s.qref,
                      slot=s._slot, positivity=(opt.rho_eps, 1e-3) if opt.limiter else None,
                      cact=s.cact)

    def high():
        s._fluxes(t, s._Fb)

    def low():
        s._low_order(Q, t, s._FL, s._alpha)

    def residual():
        s._lo_key = None
        s.residual(Q, t, dt)

    def correction():
        if s.implicit is None:
            return
        L, _ = s.residual(Q, t, dt)
        V = Q + dt * L
        if s._live_faces is None:
            s._live_faces = s.implicit.live_faces(s.live)
        s.implicit.correct(V, L[:, 1:3], dt, s.cact, s._live_faces)

    def step():
        from pedmesh.models.continuum.solver import FVState

        st = FVState(Q.copy(), t)
        st.outflow = np.zeros(s.n_exits)
        s.step(st, dt)

    cases = [("reconstruction", recon), ("high-order fluxes", high),
             ("first-order fluxes + wave speeds", low), ("residual (all of the above, "
                                                         "limiter, sources)", residual),
             ("residual + implicit correction", correction), ("whole step (2 stages)", step)]
    from pedmesh.models.continuum.solver import _one_blas_thread

    print(f"{'kernel':<48} {'1 thread med / best':>22} {'2 threads med / best':>22} "
          f"{'speed-up med / best':>20}")
    with _one_blas_thread():
        for name, fn in cases:
            times = {1: [], 2: []}
            for n in (1, 2):  # compile / warm both
                numba.set_num_threads(n)
                fn()
            for _ in range(args.repeats):
                for n in (1, 2):
                    numba.set_num_threads(n)
                    a = time.perf_counter()
                    fn()
                    times[n].append(time.perf_counter() - a)
            m1, m2 = statistics.median(times[1]), statistics.median(times[2])
            b1, b2 = min(times[1]), min(times[2])
            print(f"{name:<48} {1e3 * m1:10.2f} / {1e3 * b1:6.2f} ms {1e3 * m2:10.2f} / "
                  f"{1e3 * b2:6.2f} ms {m1 / m2:10.2f} / {b1 / b2:5.2f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
