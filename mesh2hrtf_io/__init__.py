"""Mesh2HRTF project export, NumCalc runs and SOFA collection (metres inside projects).

Not built yet: see the open issue "Mesh2HRTF project export and HRTF solving".
"""
__all__: list[str] = []
