"""The collector thresholds of the long loops (warerover_phys.util.gc_tuning)."""

import gc

import pytest

from warerover_phys.util.gc_tuning import LOOP_THRESHOLDS, long_loop


def test_long_loop_raises_the_thresholds_and_restores_them():
    old = gc.get_threshold()
    try:
        gc.set_threshold(700, 10, 10)
        with long_loop():
            assert gc.get_threshold() == LOOP_THRESHOLDS
        assert gc.get_threshold() == (700, 10, 10)
        gc.set_threshold(50_000, 5, 500)  # never lowered, only raised
        with pytest.raises(RuntimeError), long_loop():
            assert gc.get_threshold() == (50_000, LOOP_THRESHOLDS[1], 500)
            raise RuntimeError("the loop failed")
        assert gc.get_threshold() == (50_000, 5, 500)
    finally:
        gc.set_threshold(*old)
