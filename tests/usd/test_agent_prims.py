"""Agents' static prims copied from the first of their shape hold what writing each in full holds."""

from __future__ import annotations

import numpy as np
import pytest

from tests.helpers import scenarios as S
from usdcrowd.core.model import code, ROLES
from usdcrowd.scenario.stageio import StageFrame
from usdcrowd.usd.agent_prims import AgentPrims


@pytest.fixture
def crowd_of_every_shape():
    """40 people in two groups under two parents (one moving): leaders, an invisible leader, members
    following them (two following another member, one in the other group), traders, some the scenario
    defines itself, each with its own values."""
    rng = np.random.default_rng(2)
    n = 40
    a = S.agents(rng.uniform(-10, 10, (n, 2)), group=np.arange(n) % 2, height=rng.uniform(1.5, 1.9, n),
                 speed=rng.uniform(1.0, 1.5, n), role=["leader", "invisibleLeader"] + ["member"] * (n - 2),
                 personality=["civilian", "security"] * (n // 2), max_slope=rng.choice([0.5, 1.0], n))
    a.leader[2:] = np.arange(2, n) % 2
    a.leader[10], a.leader[11], a.group[12] = 4, 5, 1     # beside others of their shape: another leader, group
    a.color[:] = rng.uniform(0, 1, (n, 3))
    a.trades = np.arange(n) % 5 == 0
    a.path[:] = [f"/World/Crowd/{'Left' if i % 2 else 'Right'}/p{i}" for i in range(n)]
    a.palette = rng.uniform(0, 1, (n, 7, 3))
    sc = S.scenario(a, S.groups([[5, 0, 0], [-5, 0, 0]]))
    t = len(sc.time.codes)
    moving = np.repeat(np.eye(4)[None], t, axis=0)
    moving[:, 0, 3] = np.linspace(0.0, 3.0, t)
    parents = {"/World/Crowd/Left": moving, "/World/Crowd/Right": np.diag([2.0, 2.0, 2.0, 1.0])}
    return sc, parents, {a.path[i] for i in range(0, n, 7)}


def _layer(sc, parents, authored, copy):
    from pxr import Sdf

    layer = Sdf.Layer.CreateAnonymous(".usda")
    a = sc.agents
    prims = AgentPrims(layer, sc, StageFrame("Z", 1.0), authored, parents, ("/World/P/Skel", "/World/P/Body", ""),
                       a.palette, {i: a.start[i].tolist() for i in range(len(a))}, copy=copy)
    scale = np.linspace(0.9, 1.1, len(a))
    with Sdf.ChangeBlock():
        written = [prims.write(i, float(scale[i])) for i in range(len(a))]
    return layer, written, prims


def test_copied_agents_hold_the_specs_and_values_of_agents_written_in_full(crowd_of_every_shape):
    sc, parents, authored = crowd_of_every_shape
    copied, written, prims = _layer(sc, parents, authored, copy=True)
    full, reference, _ = _layer(sc, parents, authored, copy=False)
    assert copied.ExportToString() == full.ExportToString()
    assert [w[1] for w in written] == [r[1] for r in reference]
    assert len(prims._templates) >= 6                       # shapes: leaders, traders, authored, two parents
    a = sc.agents
    p = a.path[9]                                           # a copy: its own values, bindings and leader
    root = copied.GetPrimAtPath(p)
    assert root.attributes["crowd:agentId"].default == 10
    assert root.relationships["skel:skeleton"].targetPathList.explicitItems == [f"{p}/Skel"]
    assert root.relationships["crowd:leader"].targetPathList.explicitItems == [a.path[1]]
    assert root.attributes["crowd:personality"].default == "security"
    assert copied.GetPrimAtPath(a.path[1]).attributes["visibility"].default == "invisible"
    assert a.role[1] == code(ROLES, "invisibleLeader")
    np.testing.assert_allclose(copied.GetAttributeAtPath(f"{p}/Body.primvars:displayColor").default, a.palette[9],
                               rtol=1e-6)
    assert len(copied.GetAttributeAtPath(f"{a.path[3]}.xformOp:transform:stageFrame").GetInfo("timeSamples")) > 1
