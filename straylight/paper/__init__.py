"""The seed paper's scenarios and figures, reproduced from the same model the survey uses.

Internal: not part of the public API (``straylight.__all__``); used by ``straylight scenario``
and ``straylight figure``.
"""

__all__: list[str] = []
