"""Shots for other tools: one flattened USD layer, a usdz package, binary glTF (``usdcrowd export``).

- :mod:`.flatten`: the composed stage as one layer (value clips become
  time samples), optionally restricted to some frames, and its usdz package;
- :mod:`.axes`: usdcrowd's canonical frame (Z up, metres, row vectors) to
  glTF's (Y up, metres, column vectors), and matrices as translation,
  rotation and scale;
- :mod:`.glb`: the binary buffer of a GLB, its views and accessors;
- :mod:`.document`: the glTF document's nodes and animation keys;
- :mod:`.skins`: the crowd as skins keyed at each frame;
- :mod:`.gltf`: the whole :class:`~usdcrowd.scenario.shot_scene.ShotScene` (crowd,
  cameras, scenery) as glTF 2.0, written to a GLB.
"""
