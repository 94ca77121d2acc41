"""Numerical tolerances used across usdcrowd, in one place."""

# Skinned points computed by usdcrowd against UsdSkel's own, metres.
SKINNING_ATOL = 1e-5
# Round trip of authored float32 values through a layer.
ROUND_TRIP_ATOL = 1e-6
# A stage's metersPerUnit is taken as 1 when within this of it.
UNIT_RTOL = 1e-9
