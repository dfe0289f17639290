"""One progress bar for long commands: tqdm when installed (the ``cli`` extra), silent otherwise."""

from __future__ import annotations

import sys

__all__ = ["Progress"]


class Progress:
    """``update(n=1)`` and ``close()``; a no-op without tqdm or when ``enabled`` is false."""

    def __init__(self, total, enabled=True, desc=""):
        self.bar = None
        if enabled:
            try:
                from tqdm import tqdm
            except ImportError:
                return
            self.bar = tqdm(total=total, desc=desc, file=sys.stderr, leave=False)

    def update(self, n=1):
        if self.bar is not None:
            self.bar.update(n)

    def close(self):
        if self.bar is not None:
            self.bar.close()
