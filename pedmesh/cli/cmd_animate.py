"""``pedmesh animate``: an MP4 or GIF of a run (the density field, and the crowd)."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "write an animation of a run (density field and crowd, with a clock) as MP4 or GIF"
DESCRIPTION = """\
Write the run's output frames as a video: the density over the room (the continuum models'
cell density, the social force model's kernel density), the pedestrians as dots (particle
models) and a clock with the number out. One picture per output frame (1 s by default), at
--fps pictures per second of video. The suffix of -o picks the format: .mp4 (H.264, with
the ffmpeg of the imageio-ffmpeg wheel) or .gif.

examples:
  pedmesh animate runs/ex2-sfm -o ex2.mp4
  pedmesh animate runs/ex2-eos -o ex2.gif --fps 5
"""


def add_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("run_dir", metavar="RUN_DIR", help="a run folder")
    p.add_argument("-o", "--output", required=True, metavar="FILE",
                   help="the video to write (.mp4 or .gif)")
    p.add_argument("--fps", type=float, default=10.0,
                   help="pictures per second of video (default: 10, i.e. 10 s of run per "
                        "second at 1 s frames)")
    p.add_argument("--max-frames", type=int, default=600, metavar="N",
                   help="at most N pictures, evenly picked (default: 600)")


def run(args: argparse.Namespace) -> int:
    import time

    from ..animate import animate_run

    t0 = time.perf_counter()
    out = animate_run(Path(args.run_dir), Path(args.output), fps=args.fps,
                      max_frames=args.max_frames)
    print(f"wrote {out} ({out.stat().st_size / 1e6:.1f} MB) in "
          f"{time.perf_counter() - t0:.1f} s")
    return 0
