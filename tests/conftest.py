import os

# VTK renders off screen here; keep its fallback warnings quiet in test output
os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")
