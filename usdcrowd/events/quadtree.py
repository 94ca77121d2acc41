"""Group motions of one frame on a multi-resolution grid (seed 000, section 4.1).

The ground is cut into a world-aligned quad-tree of square cells: level 0
cells are ``cell_size`` wide, level ``L`` cells ``2**L`` times wider, and
each level-``L+1`` cell holds exactly four level-``L`` cells. Only occupied
cells are kept; keys are indexed by a dense table while the crowd's extent
is moderate (linear time, no sort) and by sorting otherwise.

Per cell, from sums gathered with ``np.bincount`` (no loop over agents):

- alignment: length of the mean unit velocity (1 = everyone the same way);
- mean speed, and speed homogeneity (coefficient of variation of speed);
- density: agents per square metre of the cell;
- type homogeneity: share of the majority character type.

A cell passing every test "forms a group motion" (is *marked*). Going up the
levels, marked cells are linked to their marked 8-neighbours, to their
marked parent, and to the marked parents of their 8-neighbours, whenever
their mean directions, speeds and majority types agree; the connected
components of these links are the groups. An agent joins the group of its
finest marked cell among the ``member_levels`` finest levels (coarser cells
only link: their agents may be tens of metres apart); agents that do not move
with their group (direction, speed, type) are left out; then moving agents of
neighbouring cells standing close to a group's members and moving with it
are taken in, so a formation cut by a cell border, or whose cell some
passers-by spoil, is not lost.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..core.model import CHARACTER_TYPES
from .params import EventParams

# Agents slower than this have no direction of motion.
_MOVING = 1e-6  # m/s
# The four "forward" neighbours: each undirected 8-neighbour link once.
_HALF_NEIGHBOURS = ((1, -1), (1, 0), (1, 1), (0, 1))
_NEIGHBOURS = tuple((dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1) if dx or dy)
_BLOCK = ((0, 0),) + _NEIGHBOURS  # a cell and its 8 neighbours
# Column in _BLOCK of the offset (dx, dy), at [(dx + 1) * 3 + dy + 1].
_BLOCK_COL = np.array([_BLOCK.index((dx, dy)) for dx in (-1, 0, 1) for dy in (-1, 0, 1)])
# Rounds of growing groups into neighbouring cells (each reaches one cell further).
_HALO_PASSES = 3
# A dense key -> cell table is used while it has at most this many entries
# per agent (or 2**16 in all); beyond, binary search (a far-flung crowd).
_LUT_PER_AGENT = 8


class _Level:
    """The occupied cells of one quad-tree level and their statistics.

    Cells are keyed ``(cx + 1) * w + (cy + 1)`` with ``0 <= cy <= w - 3``, so
    the keys of neighbours (``cx - 1 .. cx + 1``, ``cy - 1 .. cy + 1``)
    never wrap.

    Parameters
    ----------
    keys : (m,) int64
        Key of the cell of each item (agent, or child cell).
    w : int
    use_lut : bool
        Index keys with a dense table (linear time) rather than by sorting.

    Attributes
    ----------
    key : (c,) int64
        Sorted keys of the occupied cells.
    inverse : (m,) int64
        Row of each item's cell.
    cx, cy : (c,) int64
        Cell coordinates at this level (>= 0).
    n : (c,) float64
        Agents in the cell.
    su : (c, 2) float64
        Sum of unit velocities.
    ss, ss2 : (c,) float64
        Sum of speeds, of squared speeds.
    tc : (c, T) float64
        Agents per character type.
    parent : (c,) int64 or None
        Row of the parent cell in the next level (set when it is built).
    """

    def __init__(self, keys: np.ndarray, w: int, use_lut: bool):
        self.w = w
        self.lut = None
        if use_lut:
            self.lut = np.full(int(keys.max()) + 2 * w + 1, -1, np.int64)  # room for x + 1 neighbours
            self.lut[keys] = 0
            self.key = np.flatnonzero(self.lut >= 0)
            self.lut[self.key] = np.arange(len(self.key))
            self.inverse = self.lut[keys]
        else:
            self.key, inv = np.unique(keys, return_inverse=True)
            self.inverse = inv.ravel()
        self.cx, self.cy = self.key // w - 1, self.key % w - 1
        self.parent = None

    def gather(self, n, su, ss, ss2, tc, n_types):
        """Sum per cell the items' counts ``n`` (m,) (None: one each), unit
        velocities ``su`` (m, 2), speeds ``ss`` and squared speeds ``ss2``
        (m,), and type counts ``tc``: (m, T) counts, or (m,) type codes."""
        c, inv = len(self.key), self.inverse

        def bc(wts):
            return np.bincount(inv, wts, minlength=c).astype(np.float64)

        self.n = bc(n)
        self.su = np.stack([bc(su[:, 0]), bc(su[:, 1])], axis=1)
        self.ss, self.ss2 = bc(ss), bc(ss2)
        if tc.ndim == 1:
            cnt = np.bincount(inv * n_types + tc, minlength=c * n_types)
        else:
            cnt = np.bincount((inv[:, None] * n_types + np.arange(n_types)).ravel(), tc.ravel(),
                              minlength=c * n_types)
        self.tc = cnt.reshape(c, n_types).astype(np.float64)

    def find(self, cx: np.ndarray, cy: np.ndarray) -> np.ndarray:
        """(k,) row of the cells at (cx, cy), or -1 where unoccupied.

        ``cx`` may run one past either side of the occupied range, ``cy``
        one past either side of ``0 .. w - 3``.
        """
        k = (cx + 1) * self.w + (cy + 1)
        if self.lut is not None:
            inside = (k >= 0) & (k < len(self.lut))
            return np.where(inside, self.lut[np.clip(k, 0, len(self.lut) - 1)], -1)
        pos = np.minimum(np.searchsorted(self.key, k), len(self.key) - 1)
        return np.where(self.key[pos] == k, pos, -1)

    def evaluate(self, area: float, p: EventParams):
        """Mark the cells that form a group motion; keep direction, speed and type."""
        n = np.maximum(self.n, 1.0)
        mean_u = self.su / n[:, None]
        align = np.hypot(mean_u[:, 0], mean_u[:, 1])
        self.speed = self.ss / n
        std = np.sqrt(np.maximum(self.ss2 / n - self.speed ** 2, 0.0))
        self.major = np.argmax(self.tc, axis=1)
        share = self.tc[np.arange(len(n)), self.major] / n
        self.direction = mean_u / np.maximum(align, 1e-12)[:, None]
        self.marked = ((self.n >= p.cell_min_agents) & (self.n / area >= p.min_density)
                       & (align >= p.min_alignment) & (self.speed >= p.min_speed)
                       & (std <= p.max_speed_cv * self.speed) & (share >= p.min_type_share))


def _compatible(a: _Level, i, b: _Level, j, cos_merge: float, ratio: float) -> np.ndarray:
    """(k,) bool: cells ``a[i]`` and ``b[j]`` move alike (direction, speed, type)."""
    cos = np.einsum("ij,ij->i", a.direction[i], b.direction[j])
    si, sj = a.speed[i], b.speed[j]
    return ((cos >= cos_merge) & (np.maximum(si, sj) <= ratio * np.minimum(si, sj))
            & (a.major[i] == b.major[j]))


def _build_levels(ij, u, speed, ctype, n_types, levels, use_lut) -> list[_Level]:
    """Level 0 from the agents' cells ``ij`` (m, 2), then each coarser level
    from its children (the parents' sums are their children's sums)."""
    w = int(ij[:, 1].max()) + 3
    lv = _Level((ij[:, 0] + 1) * w + (ij[:, 1] + 1), w, use_lut)
    lv.gather(None, u, speed, speed * speed, ctype, n_types)
    out = [lv]
    for _ in range(levels - 1):
        up = _Level(((lv.cx >> 1) + 1) * w + ((lv.cy >> 1) + 1), w, use_lut)
        up.gather(lv.n, lv.su, lv.ss, lv.ss2, lv.tc, n_types)
        lv.parent = up.inverse
        out.append(up)
        lv = up
    return out


def _link(levels: list[_Level], p: EventParams) -> tuple[np.ndarray, np.ndarray]:
    """Connected components of the compatible marked cells.

    Links: 8-neighbours at one level; a cell and its parent; a cell and the
    parents of its 8-neighbours (a fine cell next to a coarse one across a
    border of the coarser grid).

    Returns
    -------
    offset : (levels + 1,) int64
        First node of each level.
    comp : (nodes,) int
        Component of every cell of every level (unmarked ones are alone).
    """
    cos_merge = np.cos(np.radians(p.merge_angle))
    ratio = p.merge_speed_ratio
    offset = np.cumsum([0] + [len(lv.key) for lv in levels])
    src, dst = [], []

    def add(lv, i, L, up, j, Lj):
        ok = j >= 0
        ok[ok] = up.marked[j[ok]]
        ok[ok] = _compatible(lv, i[ok], up, j[ok], cos_merge, ratio)
        src.append(offset[L] + i[ok])
        dst.append(offset[Lj] + j[ok])

    for L, lv in enumerate(levels):
        idx = np.flatnonzero(lv.marked)
        if len(idx) == 0:
            continue
        cx, cy = lv.cx[idx], lv.cy[idx]
        for dx, dy in _HALF_NEIGHBOURS:
            add(lv, idx, L, lv, lv.find(cx + dx, cy + dy), L)
        if L + 1 < len(levels):
            up = levels[L + 1]
            add(lv, idx, L, up, lv.parent[idx], L + 1)
            # The 8-neighbours fall in the parent or in (at most) three other
            # parents, on the sides where the cell touches its parent's border.
            px, py = cx >> 1, cy >> 1
            sx, sy = 2 * (cx & 1) - 1, 2 * (cy & 1) - 1
            for ox, oy in ((sx, 0), (0, sy), (sx, sy)):
                add(lv, idx, L, up, up.find(px + ox, py + oy), L + 1)
    n_nodes = int(offset[-1])
    src = np.concatenate(src) if src else np.zeros(0, np.int64)
    dst = np.concatenate(dst) if dst else np.zeros(0, np.int64)
    graph = coo_matrix((np.ones(len(src), np.int8), (src, dst)), shape=(n_nodes, n_nodes))
    return offset, connected_components(graph, directed=False)[1]


def find_groups(xy: np.ndarray, velocity: np.ndarray, character_type: np.ndarray,
                params: EventParams | None = None) -> np.ndarray:
    """Label the agents of one frame that move together.

    Parameters
    ----------
    xy : (m, 2) float
        Planar positions, metres (only the agents to consider, e.g. visible).
    velocity : (m, 2) float
        Planar velocities, m/s.
    character_type : (m,) int
        Codes into :data:`usdcrowd.core.model.CHARACTER_TYPES`.
    params : EventParams, optional

    Returns
    -------
    (m,) int64
        Group of each agent, ``0 .. g-1`` numbered by each group's first
        agent, or -1 for agents in no group motion. Groups of any size are
        returned; the tracker applies the member minimums.
    """
    p = params or EventParams()
    xy = np.asarray(xy, np.float64)
    velocity = np.asarray(velocity, np.float64)
    ctype = np.asarray(character_type, np.int64)
    m = len(xy)
    labels = np.full(m, -1, np.int64)
    if m < max(int(p.cell_min_agents), 1):
        return labels
    n_types = max(len(CHARACTER_TYPES), int(ctype.max()) + 1)
    speed, moving, u = _unit_velocities(velocity)
    levels = _evaluated_levels(xy, u, speed, ctype, n_types, p)
    if not any(lv.marked.any() for lv in levels):
        return labels
    offset, comp = _link(levels, p)
    inv0 = levels[0].inverse  # (m,) level-0 cell of each agent
    agent_comp = _cell_components(levels, offset, comp, p.member_levels)[inv0]
    has = agent_comp >= 0
    if not has.any():
        return labels
    a, g = _number_present(agent_comp[has], len(comp))
    gdir, gspeed, gtype = _group_motion(a, g, u[has], speed[has], ctype[has], n_types)
    agrees = _member_test(u, speed, moving, ctype, gdir, gspeed, gtype, p)

    # Leave out the agents of group cells that do not move with the group.
    rows = np.flatnonzero(has)
    keep = agrees(rows, a) > -np.inf
    labels[rows[keep]] = a[keep]

    if p.halo_distance > 0:
        _grow(labels, xy, moving, inv0, levels[0], agrees, p.halo_distance, p.cell_size)
    _number_by_first_agent(labels, g)
    return labels


def _unit_velocities(velocity: np.ndarray):
    """Speeds (m,), whether each agent moves (m,) bool, and unit velocities (m, 2) (zero when still)."""
    speed = np.hypot(velocity[:, 0], velocity[:, 1])
    moving = speed > _MOVING
    u = velocity / np.where(moving, speed, 1.0)[:, None]
    u[~moving] = 0.0
    return speed, moving, u


def _evaluated_levels(xy, u, speed, ctype, n_types, p: EventParams) -> list[_Level]:
    """The frame's quad-tree levels, finest first, each cell marked or not as a group motion."""
    # Level-0 cell coordinates, shifted so the coarsest cells stay world-aligned
    # (a group does not jump between cells as the crowd's bounding box moves).
    top = int(p.levels) - 1
    ij = np.floor(xy / p.cell_size).astype(np.int64)
    ij -= (ij.min(axis=0) >> top) << top
    span = (int(ij[:, 0].max()) + 3) * (int(ij[:, 1].max()) + 3)
    use_lut = span <= max(_LUT_PER_AGENT * len(xy), 1 << 16)
    levels = _build_levels(ij, u, speed, ctype, n_types, top + 1, use_lut)
    for L, lv in enumerate(levels):
        lv.evaluate((p.cell_size * 2 ** L) ** 2, p)
    return levels


def _cell_components(levels: list[_Level], offset, comp, member_levels) -> np.ndarray:
    """(c0,) int64 component of each level-0 cell's finest marked cell (itself or an ancestor), else -1."""
    # Ancestors only up to `member_levels`: coarser cells only link finer
    # ones, their agents can be far apart.
    c0 = len(levels[0].key)
    cell_comp = np.full(c0, -1, np.int64)
    anc = np.arange(c0)
    for L, lv in enumerate(levels[:max(int(member_levels), 1)]):
        if L:
            anc = levels[L - 1].parent[anc]
        take = (cell_comp < 0) & lv.marked[anc]
        cell_comp[take] = comp[offset[L] + anc[take]]
    return cell_comp


def _number_present(ids: np.ndarray, n_nodes: int) -> tuple[np.ndarray, int]:
    """The components ``ids`` (k,) that hold agents, numbered ``0 .. g-1``, and g."""
    # Linear, no sort: the ids are graph nodes, below `n_nodes`.
    present = np.zeros(n_nodes, bool)
    present[ids] = True
    rank = np.cumsum(present) - 1
    return rank[ids], int(present.sum())


def _group_motion(a, g: int, u, speed, ctype, n_types: int):
    """Direction (g, 2), mean speed (g,) and majority type (g,) of each group ``a`` (k,) of the agents given."""
    cnt = np.bincount(a, minlength=g).astype(np.float64)
    gu = np.stack([np.bincount(a, u[:, 0], g), np.bincount(a, u[:, 1], g)], axis=1)
    gdir = gu / np.maximum(np.hypot(gu[:, 0], gu[:, 1]), 1e-12)[:, None]
    gspeed = np.bincount(a, speed, g) / cnt
    gtype = np.argmax(np.bincount(a * n_types + ctype, None, g * n_types).reshape(g, n_types), axis=1)
    return gdir, gspeed, gtype


def _member_test(u, speed, moving, ctype, gdir, gspeed, gtype, p: EventParams):
    """``agrees(agent, grp)``: whether agents move with groups of this motion, by the member thresholds."""
    cos_member = np.cos(np.radians(p.member_angle))
    r = p.member_speed_ratio

    def agrees(agent, grp):
        """(k,) cosine to the group's direction where the agents move with it, else -inf."""
        cos = np.einsum("ij,ij->i", u[agent], gdir[grp])
        s, gs = speed[agent], gspeed[grp]
        ok = moving[agent] & (cos >= cos_member) & (s * r >= gs) & (s <= r * gs) & (ctype[agent] == gtype[grp])
        return np.where(ok, cos, -np.inf)

    return agrees


def _grow(labels, xy, moving, inv0, lv0: _Level, agrees, halo: float, cell_size: float) -> None:
    """Take in moving agents of the cells next to a group's members (in place).

    An agent joins when it moves with the group and stands within ``halo``
    metres of the box around the group's members in a neighbouring (or its
    own) level-0 cell: a formation cut by a cell border, or whose cell a few
    passers-by spoil, stays whole, while people a few metres away stay out.
    Repeated so the group grows through such cells.
    """
    c0 = len(lv0.key)
    # The 3 x 3 block of every level-0 cell; row c0 stands for "unoccupied".
    block = np.stack([lv0.find(lv0.cx + dx, lv0.cy + dy) for dx, dy in _BLOCK], axis=1)  # (c0, 9)
    block[block < 0] = c0
    cell_group = np.full(c0 + 1, -1, np.int64)  # row c0: the "unoccupied" cell
    lo = np.full((c0 + 1, 2), np.inf)
    hi = np.full((c0 + 1, 2), -np.inf)
    new = np.flatnonzero(labels >= 0)
    for _ in range(_HALO_PASSES):
        if len(new) == 0:
            break
        nc = inv0[new]
        unset = cell_group[nc] < 0
        cell_group[nc[unset]] = labels[new[unset]]
        mine = labels[new] == cell_group[nc]  # one group's box per cell
        for ax in range(2):
            np.minimum.at(lo[:, ax], nc[mine], xy[new[mine], ax])
            np.maximum.at(hi[:, ax], nc[mine], xy[new[mine], ax])
        # Only free agents of the cells around cells that just gained members.
        near = np.zeros(c0 + 1, bool)
        near[block[np.unique(nc)].ravel()] = True
        near[c0] = False
        free = np.flatnonzero((labels < 0) & moving & near[inv0])
        if len(free) == 0:
            break
        if 2 * halo <= cell_size:
            # Within `halo` of a neighbouring cell only on the sides of the
            # cell's quarter the agent stands in: its own cell and three others.
            f = xy[free] / cell_size
            side = np.where(f - np.floor(f) >= 0.5, 1, -1)
            cols = _BLOCK_COL[np.stack([np.full(len(free), 4), (side[:, 0] + 1) * 3 + 1,
                                        3 + side[:, 1] + 1, (side[:, 0] + 1) * 3 + side[:, 1] + 1], axis=1)]
            nb = block[inv0[free][:, None], cols]  # (k, 4)
        else:
            nb = block[inv0[free]]  # (k, 9)
        grp = cell_group[nb]
        ki, kj = np.nonzero(grp >= 0)
        cell, pt = nb[ki, kj], xy[free[ki]]
        gap = np.maximum(np.maximum(lo[cell] - pt, pt - hi[cell]), 0.0)
        close = np.hypot(gap[:, 0], gap[:, 1]) <= halo
        ki, kj = ki[close], kj[close]
        score = np.full(nb.shape, -np.inf)
        score[ki, kj] = agrees(free[ki], grp[ki, kj])
        best = np.argmax(score, axis=1)
        took = score[np.arange(len(free)), best] > -np.inf
        labels[free[took]] = grp[took, best[took]]
        new = free[took]


def _number_by_first_agent(labels: np.ndarray, g: int) -> None:
    """Number the ``g`` groups of ``labels`` (in place) by their first agent: independent of the graph."""
    has = labels >= 0
    if has.any():
        first = np.full(g, len(labels), np.int64)
        np.minimum.at(first, labels[has], np.flatnonzero(has))
        order = np.argsort(first, kind="stable")
        rank = np.empty(g, np.int64)
        rank[order] = np.arange(g)
        labels[has] = rank[labels[has]]
