"""CrowdEvent prims and camera agents read once into tables (usdcrowd.scenario.events)."""

from __future__ import annotations

import math

import numpy as np
from pxr import Sdf, Usd, UsdGeom

from usdcrowd.core import model
from usdcrowd.core.resources import data_dir
from usdcrowd.scenario import load_scenario, open_stage
from usdcrowd.scenario.events import read_camera_agents, read_events

HARBOUR = data_dir("stages") / "harbour.usda"

# Three agents (ids 5, 7, 9) and an event whose participants change over time.
MEMBERS_STAGE = '''
def Xform "World"
{
    def SkelRoot "A" (prepend apiSchemas = ["CrowdAgentAPI"])
    {
        uniform int crowd:agentId = 5
    }
    def SkelRoot "B" (prepend apiSchemas = ["CrowdAgentAPI"])
    {
        uniform int crowd:agentId = 7
    }
    def SkelRoot "C" (prepend apiSchemas = ["CrowdAgentAPI"])
    {
        uniform int crowd:agentId = 9
    }
    def CrowdEvent "Chat"
    {
        uniform token crowd:kind = "dialogue"
        rel crowd:members = [</World/A>, </World/Nobody>]
        uniform double crowd:startTime = 2
        uniform double crowd:endTime = 10
        int[] crowd:memberIds.timeSamples = {3: [5], 6: [5, 7, 99], 9: []}
        point3f crowd:center.timeSamples = {2: (0, 0, 0), 10: (8, 0, 0)}
    }
    def CrowdEvent "Static"
    {
        uniform token crowd:kind = "groupMotion"
        rel crowd:members = [</World/C>, </World/B>]
        uniform double crowd:startTime = -5
        uniform double crowd:endTime = 50
    }
}
'''

# Y up, centimetres: an event and a camera agent with every value left at its fallback.
CM_STAGE = '''
def Xform "World"
{
    def CrowdEvent "Blast"
    {
        uniform token crowd:kind = "explosion"
        uniform double crowd:startTime = 1
        uniform double crowd:endTime = 4
        point3f crowd:center = (100, 200, 300)
        float crowd:radius = 150
    }
    def Camera "Cam" (prepend apiSchemas = ["CameraAgentAPI"])
    {
        float2 clippingRange = (10, 10000)
        double3 xformOp:translate = (100, 200, 300)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
}
'''


def _rows(stage) -> dict[str, int]:
    return {str(p.GetPath()): i for i, p in enumerate(q for q in stage.Traverse() if q.HasAPI("CrowdAgentAPI"))}


def test_harbour_scenario_has_its_authored_event_and_camera_agents():
    sc = load_scenario(HARBOUR)
    (ev,) = sc.events
    assert ev.path == "/World/Events/BoatArrival" and model.EVENT_KINDS[ev.kind] == "arrival" and ev.authored
    assert (ev.start, ev.end) == (60.0, 840.0)
    assert [sc.agents.path[r] for r in ev.members] == ["/World/Crowd/Workers/GangMarket/Foreman",
                                                       "/World/Crowd/Workers/GangGodown/Tally"]
    np.testing.assert_array_equal(ev.times, np.arange(60.0, 841.0))
    assert ev.active.shape == (781, 2) and ev.active.all()
    np.testing.assert_allclose(ev.center, np.broadcast_to([10.0, 16.0, 0.0], (781, 3)))
    np.testing.assert_allclose(ev.radius, 8.0)
    assert sorted(sc.events.agent_events(100.0, len(sc.agents))[ev.members[0]]) == [0]

    cams = sc.cameras
    assert cams.path == ["/World/Cameras/ScoutWest", "/World/Cameras/ScoutEast", "/World/Cameras/Pier"]
    east = cams.path.index("/World/Cameras/ScoutEast")
    assert math.isclose(cams.max_angular_speed[east], math.radians(45))
    assert math.isclose(cams.aim_threshold[east], math.radians(12))
    assert (cams.max_speed[east], cams.max_force[east], cams.arrival_distance[east]) == (3.5, 2.5, 5.0)
    assert (cams.separation_distance[east], cams.view_angle[east]) == (6.0, 0.5)
    np.testing.assert_array_equal(cams.elevation[east], [2.0, 10.0])
    assert cams.target == [None, None, "/World/Events/BoatArrival"]
    assert [model.CAMERA_MODES[m] for m in cams.mode] == ["scouting", "scouting", "tracking"]
    # Authored in tenths of a metre (0.35, 0.36 as float), read in millimetres.
    np.testing.assert_allclose(cams.focal_length, [35.0, 35.0, 50.0], rtol=1e-6)
    np.testing.assert_allclose(cams.horizontal_aperture, [36.0] * 3, rtol=1e-6)
    np.testing.assert_allclose(cams.near, 0.1, rtol=1e-6)
    np.testing.assert_allclose(cams.far, [300.0] * 3)
    # The initial transform is the authored one (a Z-up metre stage): USD computes the same matrix.
    stage = open_stage(HARBOUR)
    for k, path in enumerate(cams.path):
        m = UsdGeom.Xformable(stage.GetPrimAtPath(path)).ComputeLocalToWorldTransform(1.0)
        np.testing.assert_allclose(cams.cam_to_world[k], np.array(m), atol=1e-6)
    np.testing.assert_allclose(cams.cam_to_world[east, 3, :3], [40.0, -38.0, 5.0])


def test_events_are_clamped_to_the_shot():
    stage = open_stage(HARBOUR)
    (ev,) = read_events(stage, {}, model.TimeRange(100.0, 200.0, 24.0))
    assert (ev.start, ev.end) == (100.0, 200.0) and len(ev.times) == 101
    assert ev.members.size == 0 and ev.active.shape == (101, 0)      # no agent rows given
    (ev,) = read_events(stage, {}, model.TimeRange(850.0, 900.0, 24.0))
    assert ev.start > ev.end and len(ev.times) == 0 and ev.sample(860.0) == -1


def test_time_sampled_member_ids_give_the_active_mask(write_stage):
    stage = open_stage(write_stage(MEMBERS_STAGE))
    rows = _rows(stage)
    a, b, c = rows["/World/A"], rows["/World/B"], rows["/World/C"]
    table = read_events(stage, rows, model.TimeRange(1.0, 12.0, 24.0))
    assert table.paths == ["/World/Chat", "/World/Static"]
    chat, static = table
    assert model.EVENT_KINDS[chat.kind] == "dialogue"
    np.testing.assert_array_equal(chat.times, np.arange(2.0, 11.0))
    assert chat.members.tolist() == sorted([a, b])          # B joins through memberIds; 99 and /World/Nobody match nobody
    who = {t: sorted(chat.members_at(t).tolist()) for t in range(1, 13)}
    # Ids hold from one sample to the next; before the first sample, the first one holds.
    assert who == {1: [], 2: [a], 3: [a], 4: [a], 5: [a], 6: sorted([a, b]), 7: sorted([a, b]), 8: sorted([a, b]),
                   9: [], 10: [], 11: [], 12: []}
    np.testing.assert_allclose(chat.center[:, 0], np.arange(9.0))        # interpolated at every frame
    np.testing.assert_allclose(chat.radius, 1.0)                         # the schema's fallback
    # Without memberIds, every member takes part from start to end (clamped to the shot).
    assert (static.start, static.end) == (1.0, 12.0) and static.active.all()
    assert static.members.tolist() == sorted([b, c])
    per_agent = table.agent_events(7.0, 3)
    assert per_agent[a] == [0] and sorted(per_agent[b]) == [0, 1] and per_agent[c] == [1]
    assert all(e.authored for e in table)


def test_events_from_the_crowd_layer_are_detected_and_come_after_authored_ones(write_stage, tmp_path):
    write_stage(MEMBERS_STAGE, name="scenario.usda")          # the scenario the crowd layer sits on
    crowd = Sdf.Layer.CreateNew(str(tmp_path / "crowd.usdc"))
    crowd.customLayerData = {"usdcrowd": {"generator": "usdcrowd simulate"}}      # what marks it generated
    for path, type_name in (("/World/Events", "Scope"), ("/World/Events/Detected_0001", "CrowdEvent")):
        spec = Sdf.CreatePrimInLayer(crowd, path)
        spec.specifier, spec.typeName = Sdf.SpecifierDef, type_name
    crowd.Save()
    shot = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    shot.subLayerPaths = ["./crowd.usdc", "./scenario.usda"]
    shot.Save()
    stage = Usd.Stage.Open(shot.identifier)
    table = read_events(stage, _rows(stage), model.TimeRange(1.0, 12.0, 24.0))
    assert table.paths == ["/World/Chat", "/World/Static", "/World/Events/Detected_0001"]
    assert [e.authored for e in table] == [True, True, False]
    # A user's own layer called crowd.usdc (no usdcrowd generator) holds authored events.
    crowd.customLayerData = {}
    crowd.Save()
    stage = Usd.Stage.Open(shot.identifier)
    assert all(e.authored for e in read_events(stage, _rows(stage), model.TimeRange(1.0, 12.0, 24.0)))


def test_y_up_centimetre_stage_gives_canonical_metres(write_stage):
    stage = open_stage(write_stage(CM_STAGE, up="Y", mpu=0.01))
    (ev,) = read_events(stage, {}, model.TimeRange(1.0, 12.0, 24.0))
    np.testing.assert_allclose(ev.center, np.broadcast_to([1.0, -3.0, 2.0], (4, 3)), atol=1e-9)
    np.testing.assert_allclose(ev.radius, 1.5, rtol=1e-6)

    cams = read_camera_agents(stage)
    assert cams.path == ["/World/Cam"]
    m = cams.cam_to_world[0]
    np.testing.assert_allclose(m[3, :3], [1.0, -3.0, 2.0], atol=1e-9)
    np.testing.assert_allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-9)     # no unit scale left
    np.testing.assert_allclose(-m[2, :3], [0.0, 1.0, 0.0], atol=1e-9)            # stage -Z is canonical +Y
    np.testing.assert_allclose(m[1, :3], [0.0, 0.0, 1.0], atol=1e-9)             # stage +Y is up
    np.testing.assert_allclose([cams.near[0], cams.far[0]], [0.1, 100.0], rtol=1e-6)
    # Fallbacks of the schema, angles in radians.
    assert math.isclose(cams.max_angular_speed[0], math.radians(60), rel_tol=1e-6)
    assert math.isclose(cams.aim_threshold[0], math.radians(15), rel_tol=1e-6)
    assert cams.max_speed[0] == 3.0 and cams.mode[0] == model.code(model.CAMERA_MODES, "scouting")
    np.testing.assert_allclose(cams.elevation[0], [1.5, 8.0])
    assert cams.target == [None]


def test_scenario_without_camera_agents_or_events_has_empty_tables(write_stage):
    sc = load_scenario(write_stage('''
    def Xform "World"
    {
        def CrowdGroup "G"
        {
            uniform int crowd:clones = 2
        }
    }
    '''))
    assert len(sc.cameras) == 0 and sc.cameras.cam_to_world.shape == (0, 4, 4)
    assert len(sc.events) == 0
