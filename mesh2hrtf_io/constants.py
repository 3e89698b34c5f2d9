"""Constants of Mesh2HRTF 1.2.4 projects (SI units inside projects, millimetres outside)."""

#: Version string written at the top of NC.inp and into parameters.json.
MESH2HRTF_VERSION = "1.2.4"
#: Speed of sound (m/s) and air density (kg/m^3): the Mesh2HRTF exporter's defaults.
SPEED_OF_SOUND_M_S = 346.18
DENSITY_KG_M3 = 1.1839
#: Lead (s) every impulse response is delayed by so that the head's lead (up to ~0.7 ms) stays causal: 30 cm of
#: travel at the default speed of sound. One value for writing HRIRs and for reading HRTFs back as HRIRs, so that
#: an HRTF file read back gives the very HRIRs written beside it.
HRIR_LEAD_S = 0.30 / SPEED_OF_SOUND_M_S
#: Normal particle velocity (m/s) of the vibrating ear element(s): the reciprocal source.
EAR_VELOCITY_M_S = 0.1
#: First node ID of user evaluation grids; must exceed the object's node count.
GRID_START_ID = 200000
#: Elements per wavelength that a mesh must resolve (conventional BEM rule).
ELEMENTS_PER_WAVELENGTH = 6.0
#: Relative path from NumCalc/source_N/ to the project root.
SOURCE_TO_ROOT = "../.."
#: A head is 120-250 mm across; anything under this many units is not in millimetres.
MIN_HEAD_EXTENT_MM = 50.0
