"""Expert policies that produce the demonstrations the learners imitate.

``scripted`` holds hand-designed controllers (no learning) for the tasks where one is easy to
write: an LQR for ``cartpole`` and inverse kinematics + PD for the reachers.
"""
