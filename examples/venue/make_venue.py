"""Write geometries/venue.json and geometries/venue_10k.json: an exhibition centre.

Three exhibition halls of about 96 x 166 m side by side, north of a 24 m deep concourse
that runs the width of the building (300 x 200 m in all, 58,800 m^2 walkable). A 2 m
partition wall separates the halls from the concourse, with an 8 m door into each hall and
4 m passages at both ends; 2 m walls divide the halls, each with a 10 m opening half-way
and 4 m passages at both ends; 1.2 m square pillars stand every 25-40 m in the halls.
Eleven exits (78 m of doors): four on the concourse's south facade, two on each side and
three on the north side, one per hall. The crowd: 31,000 people in each hall (about
1.9 /m^2, a busy fair) and 7,000 in the concourse: 100,000 in all (venue.json), or a
tenth of each (venue_10k.json).

    python examples/venue/make_venue.py [--out DIR]

``--out`` is where the two files go (default: ``geometries/``).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def rect(x0, y0, x1, y1):
    return [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]


def venue(scale: float = 1.0) -> dict:
    obstacles = []
    # partition between the concourse (y < 24) and the halls, doors at x = 50, 150, 250
    for k, (a, b) in enumerate([(4, 46), (54, 146), (154, 246), (254, 296)]):
        obstacles.append({"name": f"partition-{k + 1}", "polygon": rect(a, 24, b, 26)})
    # hall dividers with an opening at y = 105..115
    for x, hall in ((99, "ab"), (199, "bc")):
        obstacles.append({"name": f"divider-{hall}-south", "polygon": rect(x, 30, x + 2, 105)})
        obstacles.append({"name": f"divider-{hall}-north", "polygon": rect(x, 115, x + 2, 196)})
    # pillars
    k = 0
    for hall_x in (0, 100, 200):
        for px in (25, 50, 75):
            for py in (55, 85, 125, 155, 185):
                k += 1
                x, y = hall_x + px - 0.6, py - 0.6
                obstacles.append({"name": f"pillar-{k}", "polygon": rect(x, y, x + 1.2, y + 1.2)})
    exits = [
        {"name": "south-1", "polyline": [[20, 0], [28, 0]]},
        {"name": "south-2", "polyline": [[95, 0], [105, 0]]},
        {"name": "south-3", "polyline": [[195, 0], [205, 0]]},
        {"name": "south-4", "polyline": [[272, 0], [280, 0]]},
        {"name": "west-1", "polyline": [[0, 60], [0, 66]]},
        {"name": "west-2", "polyline": [[0, 140], [0, 146]]},
        {"name": "east-1", "polyline": [[300, 60], [300, 66]]},
        {"name": "east-2", "polyline": [[300, 140], [300, 146]]},
        {"name": "north-a", "polyline": [[45, 200], [51, 200]]},
        {"name": "north-b", "polyline": [[147, 200], [153, 200]]},
        {"name": "north-c", "polyline": [[249, 200], [255, 200]]},
    ]
    # the crowd stands between the rows of pillars (a start area may not cover one)
    bands = [(30, 54), (56.5, 84), (86.5, 124), (126.5, 154), (156.5, 184), (186.5, 198)]
    depth = sum(b - a for a, b in bands)
    starts = []
    for hall, (x0, x1) in zip("abc", ((2, 97), (103, 197), (203, 298))):
        counts = [round(31_000 * scale * (b - a) / depth) for a, b in bands]
        counts[-1] += round(31_000 * scale) - sum(counts)  # (the hall's total exactly)
        for k, ((a, b), n) in enumerate(zip(bands, counts)):
            starts.append({"name": f"hall-{hall}-{k + 1}", "polygon": rect(x0, a, x1, b),
                           "count": n})
    starts.append({"name": "concourse", "polygon": rect(2, 2, 298, 22),
                   "count": round(7_000 * scale)})
    total = sum(s["count"] for s in starts)
    return {
        "format": "pedmesh-room",
        "version": 1,
        "name": "venue" if scale == 1.0 else f"venue-{total // 1000}k",
        "description": (f"An exhibition centre, 300 x 200 m: three halls north of a concourse, "
                        f"45 pillars, 11 exits; {total:,} people "
                        "(examples/venue/make_venue.py)"),
        "units": "m",
        "outline": rect(0, 0, 300, 200),
        "obstacles": obstacles,
        "exits": exits,
        "start_areas": starts,
    }


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "geometries", metavar="DIR",
                    help="folder for venue.json and venue_10k.json (default: geometries/)")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for name, scale in (("venue.json", 1.0), ("venue_10k.json", 0.1)):
        path = args.out / name
        path.write_text(json.dumps(venue(scale), indent=1) + "\n")
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
