"""Tolerances and physical plausibility limits of `ppm`, in millimetres unless named otherwise.

Frame everywhere in `ppm`: millimetres, +x front (nose), +y left (interaural axis), +z up,
origin at the interaural centre.
"""

#: A pinna crop is a few centimetres across; anything smaller than this is probably in metres.
MIN_PINNA_EXTENT_MM = 20.0
#: ... and anything larger than this is probably in micrometres (or a whole scene).
MAX_PINNA_EXTENT_MM = 400.0
#: Two vertices closer than this are the same point.
MERGE_TOL_MM = 1e-6
#: Mean edge length of the template mesh.
TEMPLATE_EDGE_MM = 1.0
