"""Atomic file writes: a temporary file in the same folder, renamed over the target on success.

Stdlib only, so kernels that save their own results (BSP trees as JSON) and every front end
share one implementation; :mod:`pverosion.io` re-exports :func:`atomic_path`.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

__all__ = ["atomic_path", "file_mode"]


def _umask() -> int:
    """The process's file-creation mask (read without changing it where /proc tells it)."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def file_mode() -> int:
    """Permissions a newly written file gets here (``0o666`` less the process's umask)."""
    return 0o666 & ~_umask()


def atomic_path(path: str | os.PathLike):
    """Context manager yielding a temporary path that replaces ``path`` on success.

    The temporary file sits in the same folder with the same extension, so
    writers that pick a format by extension work; on error it is removed and
    ``path`` is left as it was.
    """
    return _AtomicPath(Path(path))


class _AtomicPath:
    def __init__(self, path: Path):
        self.path = path

    def __enter__(self) -> Path:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.stem}.", suffix=self.path.suffix, dir=self.path.parent)
        os.close(fd)
        os.chmod(tmp, file_mode())  # mkstemp creates 0600; a written file gets the usual permissions
        self.tmp = Path(tmp)
        return self.tmp

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            os.replace(self.tmp, self.path)
        else:
            self.tmp.unlink(missing_ok=True)
