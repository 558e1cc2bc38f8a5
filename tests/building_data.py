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
