"""Market trading (crowd:trades): wanderers stop face to face with resting sellers of another group."""

from __future__ import annotations

import numpy as np

from tests.helpers.scenarios import agents, groups, scenario
from usdcrowd.events import detect_events
from usdcrowd.core.model import EVENT_KINDS
from usdcrowd.sim import SimSettings, simulate
from usdcrowd.sim import params as P


def _market(trades: bool, same_group: bool = False):
    """Three sellers resting in a row and six wandering buyers around them, for 20 s."""
    sellers = [(-4.0, 0.0), (0.0, 0.0), (4.0, 0.0)]
    rng = np.random.default_rng(3)
    buyers = [tuple(p) for p in rng.uniform(-6, 6, (6, 2)) + [0, 3.5]]
    start = sellers + buyers
    group = [0] * 3 + [0 if same_group else 1] * 6
    a = agents(start, group=group, behavior=["rest"] * 3 + ["wander"] * 6, condition="isolated",
               heading=-np.pi / 2)
    a.trades = np.full(len(start), trades)
    g = groups([(np.nan,) * 3] * (1 if same_group else 2))
    return scenario(a, g, frames=24 * 20, bounds=((-12, -12), (12, 12)), seed=5)


def _trades(frames, sellers=3):
    """(buyer, seller, frames) spans where a buyer stands still within reach of a seller, facing each other."""
    pos = frames.position[..., :2]
    head = frames.heading
    out = []
    for b in range(sellers, pos.shape[1]):
        for s in range(sellers):
            d = pos[:, s] - pos[:, b]
            dist = np.linalg.norm(d, axis=1)
            ang = np.arctan2(d[:, 1], d[:, 0])
            facing_b = np.cos(head[:, b] - ang) > np.cos(np.radians(35))
            facing_s = np.cos(head[:, s] - (ang + np.pi)) > np.cos(np.radians(35))
            still = np.linalg.norm(frames.velocity[:, b], axis=1) < 0.3
            ok = (dist < P.TRADE_DISTANCE + 0.3) & facing_b & facing_s & still
            if ok.sum() >= 24 * 3:
                out.append((b, s, int(ok.sum())))
    return out


def test_a_trading_wanderer_stops_face_to_face_with_a_seller_of_another_group():
    frames = simulate(_market(True), SimSettings())
    spans = _trades(frames)
    assert spans, "at least one buyer traded for 3 s or more"
    for _, _, n in spans:
        assert n <= 24 * (P.TRADE_SECONDS[1] + 1)
    events = detect_events(frames, np.zeros(9, np.int8), np.ones(9, bool), 24.0)
    found = {tuple(e.members) for e in events if EVENT_KINDS[e.kind] == "interaction"}
    assert {(s, b) for b, s, _ in spans} <= found


def test_no_trade_without_crowd_trades_or_within_one_group():
    assert _trades(simulate(_market(False), SimSettings())) == []
    assert _trades(simulate(_market(True, same_group=True), SimSettings())) == []
