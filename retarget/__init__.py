"""illumix physics core: spectral grid, spectral libraries, relighting, sensor projection, ground
truth (illuminant weights, gain map, CCM map), exposure, sensor noise, ISP and metrics.

Pure numpy / colour-science. Nothing here does network or store I/O beyond reading spectral files.
"""

import warnings

from illumix.retarget.errors import SpectralError

# colour-science warns at import when matplotlib is absent (its plotting API); illumix never plots
# through colour, and matplotlib is only the benchmarks' extra, so the warning would be noise in
# every CLI run and service log.
warnings.filterwarnings("ignore", message='"Matplotlib" related API features are not available')

__all__ = ["SpectralError"]
