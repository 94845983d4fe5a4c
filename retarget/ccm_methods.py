"""The CCM fit's method family and default training set, by name (see :mod:`retarget.ccm`).

Pure Python, apart from :mod:`retarget.ccm` and :mod:`retarget.reflectances` (numpy,
colour-science): the command line shows these names in ``--help`` before it imports anything heavy.
"""

from __future__ import annotations

from illumix.retarget.registry import MethodRegistry

# value: whether the fit keeps white (M·1 = 1)
CCM_METHODS: MethodRegistry[bool] = MethodRegistry(
    "CCM method", {"White Preserving": True, "Unconstrained": False},
    aliases={"wp": "White Preserving", "Least Squares": "Unconstrained"})

# The reflectance set CCMs are fitted on unless another is named (a set of retarget.reflectances).
DEFAULT_TRAINING_SET = "ColorChecker N Ohta"
