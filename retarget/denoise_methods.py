"""The denoising method family by name (implementations: :mod:`retarget.denoise`).

Pure Python, like :mod:`retarget.ccm_methods`: the command line lists these names in ``--help``
before it imports numpy or OpenCV.
"""

from __future__ import annotations

from illumix.retarget.registry import MethodRegistry

_ALIASES = {"dt": "dt-guides", "domain transform": "dt-guides", "atrous": "atrous-guides",
            "demodulated": "dt-irradiance", "dt-demodulated": "dt-irradiance"}

#: name → one-line description of each guide-only linear cube denoiser.
DENOISE_METHODS: MethodRegistry[str] = MethodRegistry("denoise method", {
    "dt-irradiance": "domain-transform filter of the albedo-demodulated cube (irradiance), edges from the normal, "
                     "depth and the light group's direct light",
    "dt-guides": "domain-transform recursive filter (Gastal & Oliveira 2011), edges from the albedo and "
                 "normal AOVs",
    "atrous-guides": "edge-avoiding a-trous wavelet (Dammertz et al. 2010), weights from albedo, normal, depth",
}, aliases=_ALIASES)

#: The same family plus ``none`` (no denoising), for options that may switch it off.
DENOISE_CHOICES: MethodRegistry[str] = MethodRegistry(
    "denoise method", {"none": "no denoising (the cubes as rendered)", **dict(DENOISE_METHODS.items())},
    aliases={**_ALIASES, "off": "none"})

#: What the renderer stores and the service serves unless told otherwise.
DEFAULT_METHOD = "dt-irradiance"
