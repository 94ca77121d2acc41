"""Pictures of a simulated shot: a top-down map of every trajectory.

Scenery footprints in grey, behavior layers as faint tints, interest points as
rings, each agent's path in its clothing colour (linear RGB encoded to
sRGB), a dot where it ends, leaders outlined, a scale bar.
"""

from __future__ import annotations

import os

import numpy as np

from ..atomic import atomic_path
from ..core import model
from ..core.srgb import srgb8

_BACKGROUND = (250, 249, 246)
_OBSTACLE = (150, 150, 155)
_INTEREST = (200, 120, 0)
_TEXT = (40, 40, 40)


def trajectory_map(scenario: model.Scenario, positions: np.ndarray, out_png: str | os.PathLike,
                   width: int = 1200, title: str = "") -> str:
    """Draw every agent's path from above.

    Parameters
    ----------
    scenario : Scenario
    positions : (t, n, 3) float
        Agents' positions at sampled frames, canonical metres.
    out_png : path-like
    width : int
        Image width in pixels; the height follows the bounds' aspect.
    """
    from PIL import Image, ImageDraw

    pts = positions[..., :2]
    finite = np.isfinite(pts).all(-1)
    lo, hi = _map_bounds(scenario.bounds, pts, finite)
    scale = width / (hi[0] - lo[0])
    height = max(200, int(round((hi[1] - lo[1]) * scale)))
    img = Image.new("RGB", (width, height + 40), _BACKGROUND)
    draw = ImageDraw.Draw(img)

    def px(xy):
        xy = np.asarray(xy, dtype=np.float64)
        return np.stack([(xy[..., 0] - lo[0]) * scale, (hi[1] - xy[..., 1]) * scale], -1)

    _draw_scenery(img, draw, scenario, px, scale)
    _draw_tracks(draw, scenario.agents, pts, finite, px, scale)
    _draw_scale_bar(draw, hi[0] - lo[0], scale, width, height, title or os.path.basename(scenario.source))
    with atomic_path(out_png) as tmp:
        img.save(tmp, format="PNG")
    return os.fspath(out_png)


def _map_bounds(bounds, pts: np.ndarray, finite: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The map's (lo, hi) corners: the scenario's bounds grown to every finite position, then padded."""
    lo, hi = bounds
    if finite.any():
        lo = np.minimum(lo, pts[finite].min(0))
        hi = np.maximum(hi, pts[finite].max(0))
    pad = 0.04 * (hi - lo).max() + 1.0
    return lo - pad, hi + pad


def _draw_scenery(img, draw, scenario: model.Scenario, px, scale: float) -> None:
    """Behavior layers as tints (blast rings for generated ones), obstacles, interest points' rings."""
    from PIL import Image

    for f in scenario.fields:
        if f.values is None:
            if f.generator in (model.LAYER_GENERATORS.index("explosion"), model.LAYER_GENERATORS.index("volcano")):
                c = px(f.origin[:2])
                r = f.radius * scale
                draw.ellipse([c[0] - r, c[1] - r, c[0] + r, c[1] + r], outline=(220, 60, 40), width=2)
            continue
        a0, a1 = px(f.extent_min), px(f.extent_max)
        v = f.values
        span = float(v.max() - v.min()) or 1.0
        tint = Image.fromarray(np.uint8(255 - 60 * (v - v.min()) / span)).resize(
            (max(1, int(a1[0] - a0[0])), max(1, int(a0[1] - a1[1]))))
        img.paste(Image.merge("RGB", (tint, tint, tint.point(lambda x: min(255, x + 10)))), (int(a0[0]), int(a1[1])))
    for poly in scenario.obstacles.polygons:
        draw.polygon([tuple(p) for p in px(poly)], fill=_OBSTACLE)
    for p, r in zip(scenario.interest.position, scenario.interest.radius):
        c, rr = px(p[:2]), r * scale
        draw.ellipse([c[0] - rr, c[1] - rr, c[0] + rr, c[1] + rr], outline=_INTEREST, width=2)


def _draw_tracks(draw, a: model.AgentTable, pts: np.ndarray, finite: np.ndarray, px, scale: float) -> None:
    """Each agent's path in its clothing colour (grey if hidden), a dot where it ends, leaders outlined."""
    colors = srgb8(a.color)
    line_w = max(1, int(round(scale * 0.06)))
    dot = max(2.0, scale * 0.25)
    leaders = set(np.flatnonzero(a.role != model.ROLES.index("member")))
    for i in range(len(a)):
        track = px(pts[:, i][finite[:, i]])
        if len(track) == 0:
            continue
        col = tuple(int(c) for c in colors[i])
        if not a.visible[i]:
            col = (120, 120, 120)
        if len(track) > 1:
            draw.line(track.ravel().tolist(), fill=col, width=line_w)
        x, y = track[-1]
        outline = (0, 0, 0) if i in leaders else col
        draw.ellipse([x - dot, y - dot, x + dot, y + dot], fill=col, outline=outline, width=2 if i in leaders else 1)


def _draw_scale_bar(draw, span: float, scale: float, width: int, height: int, label: str) -> None:
    """A scale bar under the map and the ``label`` at its right."""
    # The largest round number of metres under a fifth of the width.
    metres = 10 ** np.floor(np.log10(span / 5))
    for m in (5 * metres, 2 * metres, metres):
        if m * scale < width / 5:
            break
    y0 = height + 20
    draw.line([(20, y0), (20 + m * scale, y0)], fill=_TEXT, width=3)
    draw.text((25 + m * scale, y0 - 7), f"{m:g} m", fill=_TEXT)
    draw.text((width - 10 - 7 * len(label), y0 - 7), label, fill=_TEXT)


KIND_NAMES = {"static": "static (placed knowing the whole shot)", "static_start": "static (placed on the first frame)"}


def coverage_plot(series: dict, column: str, n_cameras: int, out_png: str | os.PathLike, fps: float) -> str:
    """Seed 000's Figures 12 to 15: a per-frame share over time, autonomous above static (each placement).

    Parameters
    ----------
    series : dict[str, CoverageSeries]
        ``{"autonomous": ..., "static": ..., "static_start": ...}``, one panel each.
    column : str
        "active_share" (active score / all seen, Figures 12 and 13) or
        "viewed_share" (active characters viewed / all active, 14 and 15).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    label = {"active_share": "active / (active + idle) score", "viewed_share": "active characters viewed"}[column]
    fig, axes = plt.subplots(len(series), 1, figsize=(8, 2.5 * len(series)), sharex=True, constrained_layout=True)
    names = ("active", "idle") if column == "active_share" else ("viewed", "not viewed")
    for ax, (kind, s) in zip(axes, series.items()):
        y = getattr(s, column)
        t = (s.times - s.times[0]) / fps
        defined = np.isfinite(y)            # frames with nothing seen (or nobody active) stay blank
        ax.fill_between(t, 0, np.where(defined, y, 0), where=defined, color="0.35", step="mid", label=names[0])
        ax.fill_between(t, np.where(defined, y, 0), 1, where=defined, color="0.85", step="mid", label=names[1])
        ax.set_ylim(0, 1)
        ax.set_ylabel("share")
        mean = f"mean {np.mean(y[defined]):.2f}" if defined.any() else "nothing to measure"
        ax.set_title(f"{n_cameras} {KIND_NAMES.get(kind, kind)} cameras: {label} ({mean})", fontsize=10)
    axes[-1].set_xlabel("seconds")
    axes[0].legend(loc="upper right", fontsize=8)
    with atomic_path(out_png) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)
    return os.fspath(out_png)
