"""Ground truth from rendered frames: per-agent boxes, masks, keypoints, visibility and
what the stage says about each agent, exported as per-frame JSON, MOTChallenge and COCO.

:mod:`.annotate` turns one :class:`~usdcrowd.render.final.frame.FrameResult`
into a JSON-ready record; the exporters read those records back.
"""
