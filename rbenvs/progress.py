"""One progress bar for long commands: tqdm when installed (the ``cli`` extra), else a line of
text on stderr (the core install has no tqdm: a long command must not look hung)."""

from __future__ import annotations

import sys
import time

__all__ = ["Progress"]

# the plain-text fallback's seconds between lines: a terminal's line is rewritten in place often,
# a log file (CI) gets a new line rarely
TERMINAL_INTERVAL, LOG_INTERVAL = 0.5, 10.0


class _TextBar:
    """``desc: k/total (p%) s`` on ``stream``: at the start, then at most once per interval
    (rewritten in place on a terminal), and at the close."""

    def __init__(self, total, desc: str, stream):
        self.total, self.desc, self.stream = total, desc, stream
        self.count = 0
        self.terminal = bool(getattr(stream, "isatty", lambda: False)())
        self.interval = TERMINAL_INTERVAL if self.terminal else LOG_INTERVAL
        self.start = self.last = time.monotonic()
        self._write()

    def _write(self, final: bool = False) -> None:
        share = f" ({100 * self.count / self.total:.0f}%)" if self.total else ""
        line = (
            f"{self.desc or 'progress'}: {self.count}/{self.total if self.total else '?'}{share} "
            f"{time.monotonic() - self.start:.0f} s"
        )
        end = "\n" if final or not self.terminal else ""
        self.stream.write(("\r" + line if self.terminal else line) + end)
        self.stream.flush()

    def update(self, n=1):
        self.count += n
        now = time.monotonic()
        if now - self.last >= self.interval:
            self.last = now
            self._write()

    def close(self):
        self._write(final=True)


class Progress:
    """``update(n=1)`` and ``close()``; a no-op when ``enabled`` is false."""

    def __init__(self, total, enabled=True, desc=""):
        self.bar = None
        if enabled:
            try:
                from tqdm import tqdm
            except ImportError:
                self.bar = _TextBar(total, desc, sys.stderr)
                return
            self.bar = tqdm(total=total, desc=desc, file=sys.stderr, leave=False)

    def update(self, n=1):
        if self.bar is not None:
            self.bar.update(n)

    def close(self):
        if self.bar is not None:
            self.bar.close()
            self.bar = None
