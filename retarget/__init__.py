"""illumix physics core: spectral grid, spectral libraries, relighting, sensor projection, ground
truth (illuminant weights, gain map, CCM map), exposure, sensor noise, ISP and metrics.

Pure numpy / colour-science. Nothing here does network or store I/O beyond reading spectral files.
"""

from retarget.errors import SpectralError

__all__ = ["SpectralError"]
