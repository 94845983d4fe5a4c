"""The catalogue: every piece of furniture and clutter the generator can build, by name.

``FURNITURE`` and ``CLUTTER`` map a kind to its builder ``(rng, mats, name) -> Item``
(:mod:`scenegen.furniture`, :mod:`scenegen.clutter`). ``TABLETOP`` names what stands on tops,
``WALL_ITEMS`` what hangs on walls, ``FLOOR_CLUTTER`` what lies or stands on the floor (a rug is
placed anywhere and may lie under furniture; the rest stands against a wall).
"""

from __future__ import annotations

from illumix.scenegen.clutter import FLOOR, WALL
from illumix.scenegen.clutter import TABLETOP as _TABLETOP
from illumix.scenegen.furniture import FURNITURE_BUILDERS

FURNITURE = dict(FURNITURE_BUILDERS)
CLUTTER = {**_TABLETOP, **WALL, **FLOOR}
TABLETOP = sorted(_TABLETOP)
WALL_ITEMS = sorted(WALL)
FLOOR_CLUTTER = sorted(FLOOR)
