"""The one place where millimetres become metres (a Mesh2HRTF project is in SI units)."""
import numpy as np

MM_PER_M = 1000.0


def mm_to_m(values_mm: np.ndarray) -> np.ndarray:
    """Millimetres to metres (new float64 array)."""
    return np.asarray(values_mm, dtype=np.float64) / MM_PER_M


def m_to_mm(values_m: np.ndarray) -> np.ndarray:
    """Metres to millimetres (new float64 array)."""
    return np.asarray(values_m, dtype=np.float64) * MM_PER_M
