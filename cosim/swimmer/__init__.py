"""The swimmer's domain on top of the generic master: the paper's 4-phase stroke and its controller
block kind, thrust metrics, which periods of a hardware run count, and run_scene, which runs a
scene and measures it. The master never imports this room."""
