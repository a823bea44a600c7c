import multiprocessing as mp

import numpy as np
import pytest

from vishap._core.errors import ShapeError
from vishap.runtime.mailbox import Mailbox


def test_empty_mailbox_reads_zero_sequence():
    with Mailbox(4) as box:
        values, seq = box.read()
        assert seq == 0
        np.testing.assert_array_equal(values, np.zeros(4))


def test_latest_value_wins():
    with Mailbox(3) as box:
        box.write([1, 2, 3])
        assert box.write([4, 5, 6]) == 2
        values, seq = box.read()
        assert seq == 2
        np.testing.assert_array_equal(values, [4, 5, 6])


def test_wrong_size_is_refused_by_name():
    with Mailbox(3) as box:
        with pytest.raises(ShapeError, match="expected 3 values"):
            box.write([1, 2])
    with pytest.raises(ShapeError, match="size"):
        Mailbox(0)


def test_reader_keeps_last_record_while_write_in_progress():
    with Mailbox(2) as box:
        box.write([7, 8])
        box.read()
        box._seq[0] += 1  # a write is under way
        values, seq = box.read()
        np.testing.assert_array_equal(values, [7, 8])
        assert seq == 1


def _writer(name: str, size: int, n: int) -> None:
    box = Mailbox.attach(name, size)
    for i in range(1, n + 1):
        box.write(np.full(size, float(i)))
    box.close()


def test_concurrent_reads_are_never_torn():
    size, n = 512, 20000
    with Mailbox(size) as box:
        proc = mp.get_context("spawn").Process(target=_writer, args=(box.name, size, n))
        proc.start()
        seen = 0
        while proc.is_alive() or seen < n:
            values, seq = box.read()
            if seq:
                # a torn record would mix two writes
                assert np.all(values == values[0]), "torn read"
                assert values[0] == seq
                seen = seq
            if not proc.is_alive() and seq == n:
                break
        proc.join(10)
        assert proc.exitcode == 0
        assert box.read()[1] == n
