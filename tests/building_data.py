"""A small building for the tests: two storeys joined by one stair (4 m run, 3 m rise)
in a notch of both floors, an exit on the ground floor."""

NOTCHED = [[0, 0], [20, 0], [20, 10], [12, 10], [12, 8], [8, 8], [8, 10], [0, 10]]
TWO = {
    "name": "two-storey",
    "levels": [
        {"name": "ground", "z": 0.0, "outline": NOTCHED,
         "exits": [{"name": "front", "polyline": [[0, 3], [0, 5]]}],
         "start_areas": [{"name": "hall", "polygon": [[12, 1], [18, 1], [18, 6], [12, 6]],
                          "spacing": 1.0}]},
        {"name": "first", "z": 3.0, "outline": NOTCHED,
         "start_areas": [{"name": "offices", "polygon": [[2, 1], [8, 1], [8, 6], [2, 6]],
                          "spacing": 1.0}]},
    ],
    "stairs": [{"name": "stair", "polygon": [[8, 8], [12, 8], [12, 10], [8, 10]],
                "bottom": {"level": "ground", "edge": [[8, 8], [8, 10]]},
                "top": {"level": "first", "edge": [[12, 8], [12, 10]]}}],
}

#: a floor with two stair notches (issue 45's tower: benchmarks/building_steps.py)
TWO_NOTCHES = [[0, 0], [20, 0], [20, 10], [16, 10], [16, 8], [12, 8], [12, 10], [8, 10],
               [8, 8], [4, 8], [4, 10], [0, 10]]


def tower(levels: int, crowded: tuple[int, ...] | None = None, count: int = 10) -> dict:
    """A tower of ``levels`` 20 x 10 m floors 3 m apart, its stairs in the two notches in
    turn (each stair's top edge meets the next one's bottom on the landing), the exit on
    the ground floor, and ``count`` people in the start area of each floor ``crowded``
    (default: the top floor)."""
    crowded = (levels - 1,) if crowded is None else crowded
    out = []
    for k in range(levels):
        lv = {"name": f"L{k}", "z": 3.0 * k, "outline": TWO_NOTCHES}
        if k == 0:
            lv["exits"] = [{"name": "front", "polyline": [[0, 3], [0, 5]]}]
        if k in crowded:
            lv["start_areas"] = [{"name": f"area{k}", "count": count,
                                  "polygon": [[2, 1], [8, 1], [8, 6], [2, 6]]}]
        out.append(lv)
    stairs = []
    for k in range(levels - 1):
        a, b = (4, 8) if k % 2 == 0 else (12, 16)
        stairs.append({"name": f"S{k}", "polygon": [[a, 8], [b, 8], [b, 10], [a, 10]],
                       "bottom": {"level": f"L{k}", "edge": [[a, 8], [a, 10]]},
                       "top": {"level": f"L{k + 1}", "edge": [[b, 8], [b, 10]]}})
    return {"format": "pedmesh-room", "version": 1, "name": f"tower{levels}", "units": "m",
            "levels": out, "stairs": stairs}
