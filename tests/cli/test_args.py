"""Shared argument parsing: frame specs like usdrecord's."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from usdcrowd.cli.args import parse_frames


@pytest.mark.parametrize("spec, expected", [
    ("10", [10]), ("1:4", [1, 2, 3, 4]), ("1:48x12", [1, 13, 25, 37]), ("1:49x12", [1, 13, 25, 37, 49]),
    ("0:1x0.5", [0, 0.5, 1]), (" 2 : 6 x 2 ", [2, 4, 6]),
])
def test_frame_specs(spec, expected):
    assert np.allclose(parse_frames(spec), expected)


@pytest.mark.parametrize("spec", ["", "a:b", "5:1", "1:5x0", "1:5x-1", "1::5"])
def test_bad_frame_specs(spec):
    with pytest.raises(argparse.ArgumentTypeError):
        parse_frames(spec)
