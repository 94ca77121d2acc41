"""Reading scenario stages into plain arrays (the only reader of crowd data)."""

from .read import load_scenario, stored_seed
from .stageio import StageFrame, open_stage, stage_frame

__all__ = ["StageFrame", "load_scenario", "open_stage", "stage_frame", "stored_seed"]
