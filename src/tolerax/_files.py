"""Files written whole: the one way tolerax writes a result, a checkpoint or a scene file (a
light module: the command line imports it before the simulator)."""

import os
import pathlib
import uuid
from collections.abc import Callable


def atomic_write(path, write: Callable[[pathlib.Path], object] | str | bytes) -> None:
    """Write the file `path` whole: `write(tmp)` writes a temporary path beside it (or `write` is
    the text or bytes to write), which is then renamed over `path` (`os.replace`, atomic). An
    interrupted or failed write leaves the old file as it was (or none), never a truncated one,
    and no temporary file behind."""
    path = pathlib.Path(path)
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        if isinstance(write, bytes):
            tmp.write_bytes(write)
        elif isinstance(write, str):
            tmp.write_text(write, encoding="utf-8")
        else:
            write(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def save_figure(fig, path, **kwargs) -> None:
    """`fig.savefig(path, **kwargs)` written whole (`atomic_write`); the format from the suffix."""
    fmt = pathlib.Path(path).suffix.lstrip(".") or None
    atomic_write(path, lambda tmp: fig.savefig(tmp, format=fmt, **kwargs))
