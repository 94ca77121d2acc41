"""Rendering a shot: the shared per-frame scene reader, the Mitsuba final path and the OpenGL preview.

Backends are imported only where used; this package's import is cheap.
"""
