"""Compiled loops are built again when the constants they froze change (usdcrowd.compiled)."""

import types
from pathlib import Path

import numpy as np

from usdcrowd.compiled import constants_digest, forget_stale_machine_code


def _constants(gain=3.0, table=(1.0, 2.0)):
    module = types.ModuleType("fake_params")
    module.GAIN, module.TABLE, module.lower_case = gain, np.array(table), "ignored"
    return module


def test_cached_machine_code_goes_when_a_constant_it_froze_changes(tmp_path):
    kernels = tmp_path / "kernels.py"
    kernels.write_text("")
    cache = tmp_path / "__pycache__"
    cache.mkdir()
    built = [cache / "kernels.step-40.py311.nbi", cache / "kernels.step-40.py311.1.nbc"]
    other = cache / "grid.cells-12.py311.nbi"          # another module's code stays
    for f in (*built, other):
        f.write_bytes(b"machine code")

    assert forget_stale_machine_code(str(kernels), _constants())          # no record yet: built again
    assert not any(f.exists() for f in built) and other.exists()
    for f in built:
        f.write_bytes(b"machine code")
    assert not forget_stale_machine_code(str(kernels), _constants())      # the same values: kept
    assert all(f.exists() for f in built)
    assert forget_stale_machine_code(str(kernels), _constants(table=(1.0, 2.5)))   # an array entry changed
    assert not any(f.exists() for f in built) and other.exists()
    assert (cache / "kernels.constants").read_text() == constants_digest(_constants(table=(1.0, 2.5)))


def test_the_digest_sees_every_upper_case_value_and_nothing_else():
    base = constants_digest(_constants())
    assert constants_digest(_constants(gain=3.0000001)) != base
    assert constants_digest(_constants(table=(1.0, 2.0, 3.0))) != base
    assert constants_digest(_constants(table=(1.0, 2.0 + 1e-12))) != base      # below numpy's printed digits
    changed = _constants()
    changed.lower_case = "something else"
    assert constants_digest(changed) == base


def test_the_step_and_the_pose_record_what_they_were_built_with():
    from usdcrowd.character import gait, kernels as pose_kernels, rig
    from usdcrowd.sim import kernels as step_kernels, params

    for module, sources in ((step_kernels, (params,)), (pose_kernels, (gait, rig))):
        stamp = Path(module.__file__).parent / "__pycache__" / "kernels.constants"
        assert stamp.read_text() == constants_digest(*sources)
