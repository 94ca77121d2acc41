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


LOADER = """
import numpy as np
from usdcrowd.sim import kernels
print("calling", flush=True)
kernels.moved_beyond(np.zeros((2, 3), np.float32), np.arange(3), np.zeros((2, 3), np.float32), 1.0)
print("done", flush=True)
"""


HELD = """
import os, signal, sys, time
from usdcrowd.compiled import cache_folder_held
with cache_folder_held(sys.argv[1]):
    os.kill(os.getpid(), signal.SIGTERM)      # lands mid-load
    time.sleep(0.3)
    print("loaded", flush=True)
print("after", flush=True)
"""


def test_machine_code_is_loaded_one_process_at_a_time_and_a_kill_waits_for_the_load(tmp_path):
    """numba's index and data files, read or written by two runs at once or cut by a stop between the
    two, crash the next run inside LLVM: every load holds the cache folder (another run waits, and can
    be stopped while it waits) and a stop that lands during the load is delivered once it is done."""
    import fcntl
    import os
    import signal
    import subprocess
    import sys
    import time

    from usdcrowd.compiled import LOCK_NAME
    from usdcrowd.sim import kernels          # its constants' stamp is written before the folder is held

    folder = kernels.moved_beyond._cache.cache_path
    assert os.path.samefile(folder, Path(kernels.__file__).parent / "__pycache__")
    root = Path(kernels.__file__).parents[2]
    env = {**os.environ, "PYTHONPATH": str(root)}
    fd, proc = os.open(os.path.join(folder, LOCK_NAME), os.O_RDWR | os.O_CREAT, 0o666), None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)                 # another run is loading or saving
        proc = subprocess.Popen([sys.executable, "-c", LOADER], stdout=subprocess.PIPE, text=True,
                                cwd=tmp_path, env=env)
        assert proc.stdout.readline() == "calling\n"
        time.sleep(2.0)
        assert proc.poll() is None, "loaded while another run held the cache"
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(10) == -signal.SIGTERM and proc.stdout.read() == ""   # stopped while it waited
    finally:
        fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)
        if proc is not None and proc.poll() is None:
            proc.kill()
    held = subprocess.run([sys.executable, "-c", HELD, str(tmp_path)], capture_output=True, text=True,
                          env=env, timeout=60)
    assert held.returncode == -signal.SIGTERM and held.stdout == "loaded\n", (held.stdout, held.stderr)


def test_every_cached_kernel_loads_through_the_lock():
    from numba.core.dispatcher import Dispatcher

    from usdcrowd.character import kernels as pose
    from usdcrowd.render.preview import instancing
    from usdcrowd.sim import kernels as crowd

    found = 0
    for module in (crowd, pose, instancing):
        for value in vars(module).values():
            for d in (value, getattr(value, "serial", None), getattr(value, "parallel", None)):
                if isinstance(d, Dispatcher) and getattr(d._cache, "cache_path", None):
                    assert hasattr(d._cache.load_overload, "__wrapped__"), d
                    assert hasattr(d._cache.save_overload, "__wrapped__"), d
                    found += 1
    assert found >= 40
