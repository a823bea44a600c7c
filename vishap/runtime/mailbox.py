"""Latest-value hand-over between processes through shared memory (a seqlock).

A producer (vision, at camera rate) publishes a fixed-shape float64 record; a consumer (the 1 kHz
servo) reads the newest complete record without ever blocking or waiting for the producer, and
without pickling: the record lives in a ``multiprocessing.shared_memory`` block. The block holds
a sequence counter followed by the payload. The writer makes the counter odd, writes, and makes it
even again; a reader copies the payload and accepts it only when the counter was even and
unchanged across the copy. If a write is in progress the reader returns the last record it
accepted (a latest-value channel never needs more).

One writer per mailbox. The creator owns the block (``close(unlink=True)``); other processes
attach by name.
"""
from __future__ import annotations

from multiprocessing import shared_memory

import numpy as np

from vishap._core.errors import ShapeError

__all__ = ["Mailbox"]

_HEADER = 8  # uint64 sequence counter


class Mailbox:
    """A single-writer, many-reader latest-value record of ``size`` float64 values."""

    def __init__(self, size: int, *, name: str | None = None, create: bool = True):
        if int(size) <= 0:
            raise ShapeError(f"Mailbox: size must be a positive number of values, got {size!r}")
        self.size = int(size)
        nbytes = _HEADER + 8 * self.size
        if create:
            self._shm = shared_memory.SharedMemory(name=name, create=True, size=nbytes)
            self._shm.buf[:nbytes] = bytes(nbytes)
        else:
            if name is None:
                raise ValueError("Mailbox: attaching needs the mailbox name")
            self._shm = shared_memory.SharedMemory(name=name, create=False)
            if self._shm.size < nbytes:
                raise ShapeError(f"Mailbox '{name}': holds {self._shm.size} bytes, expected {nbytes}")
        self._owner = create
        self._seq = np.ndarray((1,), dtype=np.uint64, buffer=self._shm.buf, offset=0)
        self._data = np.ndarray((self.size,), dtype=np.float64, buffer=self._shm.buf, offset=_HEADER)
        self._last = np.zeros(self.size)
        self._last_seq = 0
        self._scratch = np.empty(self.size)

    @property
    def name(self) -> str:
        return self._shm.name

    @classmethod
    def attach(cls, name: str, size: int) -> "Mailbox":
        return cls(size, name=name, create=False)

    # -- writer ---------------------------------------------------------------------------------
    def write(self, values) -> int:
        """Publish ``values`` (``size`` floats); returns the new sequence number."""
        v = np.asarray(values, dtype=np.float64).reshape(-1)
        if v.shape[0] != self.size:
            raise ShapeError(f"Mailbox.write: expected {self.size} values, got {v.shape[0]}")
        s = int(self._seq[0])
        if s % 2:  # a writer died mid-write; restore an even count first
            s += 1
        self._seq[0] = s + 1
        self._data[:] = v
        self._seq[0] = s + 2
        return (s + 2) // 2

    # -- reader ---------------------------------------------------------------------------------
    def read(self, retries: int = 4) -> tuple[np.ndarray, int]:
        """Newest complete record and its sequence number (0: nothing written yet).

        Never blocks: after ``retries`` torn reads it returns the last accepted record.
        """
        for _ in range(retries):
            s1 = int(self._seq[0])
            if s1 % 2:
                continue
            self._scratch[:] = self._data
            if int(self._seq[0]) == s1:
                self._last[:] = self._scratch
                self._last_seq = s1 // 2
                break
        return self._last.copy(), self._last_seq

    def close(self, unlink: bool | None = None) -> None:
        unlink = self._owner if unlink is None else unlink
        # drop our views before closing the mapping
        del self._seq, self._data
        self._shm.close()
        if unlink:
            try:
                self._shm.unlink()
            except FileNotFoundError:
                pass

    def __enter__(self) -> "Mailbox":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
