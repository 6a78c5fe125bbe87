import os

# Headless rendering for tests, whatever the machine (set before dm_control is imported).
os.environ.setdefault("MUJOCO_GL", "egl")
