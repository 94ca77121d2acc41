"""Reading scenario stages into plain arrays (the only reader of crowd data).

:func:`load_scenario` reads a scenario; :func:`read_events` and
:func:`read_camera_agents` its events and camera agents; :func:`read_crowd`
turns a shot's crowd layer back into frames.
"""

from .crowd import CrowdInfo, read_crowd
from .events import read_camera_agents, read_events
from .read import load_scenario, shot_scenario, stored_seed
from .stageio import StageFrame, open_stage, stage_frame, time_range

__all__ = ["CrowdInfo", "StageFrame", "load_scenario", "open_stage", "read_camera_agents", "read_crowd",
           "read_events", "shot_scenario", "stage_frame", "stored_seed", "time_range"]
