"""The search behind :func:`meshbits.compress`: the (B, V) of fewest bytes within an error
budget, or of least error within a size budget, found from measurements.

Each pass plans from what is known, builds candidates (simplify, quantize, encode: cheap
next to measuring), measures the one it ranks best, and updates:

- **Quantization error** in closed form, **combined error** of a level and its
  quantization, **tessellation error** of a level from its measurements
  (:mod:`.error_model`).
- **Size** from real encodings of the candidates.

The modules, each importing only those above it:

- :mod:`.error_model`: the closed-form predictions and what a measurement teaches them.
- :mod:`.levels`: a level of detail (:class:`Level`), its vertex attributes, and
  simplification with the original vertices a level strays from locked.
- :mod:`.level_cache`: the levels built (simplified and encoded once) and their predicted
  tessellation error (:class:`LevelCache`).
- :mod:`.measurements`: the passes measured (:class:`Iteration`) and how they rank.
- :mod:`.candidates`: which (level, B) to measure next (:class:`Planner`).
- :mod:`.certify`: the answer measured again with a certified bound (:class:`Certifier`).
- :mod:`.search`: the state and steps (:class:`Search`: propose, measure, run, best,
  certify).
"""

from .candidates import BITS_ABOVE, STOP_GAIN, Candidate, Planner
from .certify import ANSWER_REFINE_BUDGET, Certifier
from .error_model import (
    COMBINE_DELTA,
    KAPPA_PRIOR,
    QUANTIZATION_FACTOR,
    allowed_tessellation,
    combined_error,
    interaction,
    quantization_error,
)
from .level_cache import Codec, LevelCache, Refused
from .levels import BASE_FACES, Attributes, Level
from .measurements import Iteration
from .search import Search

__all__ = [
    "ANSWER_REFINE_BUDGET",
    "BASE_FACES",
    "BITS_ABOVE",
    "COMBINE_DELTA",
    "KAPPA_PRIOR",
    "QUANTIZATION_FACTOR",
    "STOP_GAIN",
    "Attributes",
    "Candidate",
    "Certifier",
    "Codec",
    "Iteration",
    "Level",
    "LevelCache",
    "Planner",
    "Refused",
    "Search",
    "allowed_tessellation",
    "combined_error",
    "interaction",
    "quantization_error",
]
