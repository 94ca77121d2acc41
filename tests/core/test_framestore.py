"""The positions the cameras read back from disk are the ones appended."""

from __future__ import annotations

import os

import numpy as np
import pytest

from usdcrowd.core.framestore import FrameStore, frame_blocks


def test_frames_read_back_as_appended(rng, tmp_path):
    whole = rng.normal(size=(23, 5, 3)).astype(np.float32)
    with FrameStore(5, folder=tmp_path) as store:
        for s in range(0, 23, 4):
            store.append(whole[s:s + 4])
        assert store.shape == (23, 5, 3) and len(store) == 23
        assert np.array_equal(store[0], whole[0]) and np.array_equal(store[-1], whole[-1])
        assert np.array_equal(store[3:17], whole[3:17]) and np.array_equal(store[::5], whole[::5])
        assert np.array_equal(store[2:9, [1, 4], :2], whole[2:9, [1, 4], :2])
        assert np.array_equal(np.asarray(store), whole)
        assert np.array_equal(np.concatenate(list(frame_blocks(store, size=6))), whole)
        assert np.array_equal(np.concatenate(list(frame_blocks(store, start=5, size=7))), whole[5:])
        assert store[30:].shape == (0, 5, 3)
        with pytest.raises(IndexError):
            store[23]
        with pytest.raises(ValueError):
            store.append(whole[:, :4])
        # The file has no name: nothing to leave behind in the output folder.
        assert os.listdir(tmp_path) == []
