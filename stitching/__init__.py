"""Stitching the aligned PPM pinna onto a head mesh and remeshing it for BEM (millimetres).

Not built yet: see the open issue "Stitch the aligned pinna onto the head and remesh it for BEM".
"""
__all__: list[str] = []
