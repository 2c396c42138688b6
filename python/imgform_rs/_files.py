"""Input files read whole, refusing what is not a regular file.

A FIFO among a batch's inputs would block its read until a writer came, and a
link to ``/dev/zero`` would read without end: both would hang a whole batch.
The file is opened without blocking and checked by the descriptor, so a name
swapped between the check and the read changes nothing.
"""

from __future__ import annotations

import errno
import os
import stat

_KINDS = {
    stat.S_ISDIR: "a folder",
    stat.S_ISFIFO: "a FIFO (named pipe)",
    stat.S_ISCHR: "a character device",
    stat.S_ISBLK: "a block device",
    stat.S_ISSOCK: "a socket",
}


def read_regular(path: str | os.PathLike[str]) -> bytes:
    """The bytes of the regular file at ``path`` (through links); an OSError
    naming the kind of anything else."""
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            kind = next((name for test, name in _KINDS.items() if test(mode)), "not a file")
            raise OSError(errno.EINVAL, f"{kind}, not a regular file", os.fspath(path))
        with os.fdopen(fd, "rb", closefd=False) as f:
            return f.read()
    finally:
        os.close(fd)
