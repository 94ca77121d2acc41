"""The pure core: the types every stage of the pipeline shares, with no USD and no renderer.

- :mod:`.model`       Scenario, AgentTable, CrowdFrames, events, camera agents (numpy);
- :mod:`.view`        the camera model (CameraView, projection, look_at);
- :mod:`.shading`     lights and materials as renderers need them;
- :mod:`.geometry`    meshes as triangles;
- :mod:`.framestore`  per-frame arrays that wait on disk;
- :mod:`.errors`, :mod:`.limits`, :mod:`.tolerances`, :mod:`.resources`: one-line errors,
  resource bounds, numeric tolerances in one place, the package's data files.

Everything else depends on this package; it depends on nothing of usdcrowd's.
"""
