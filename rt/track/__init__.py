"""Following the audience with a camera (`viewcomp track`): OpenCV and numpy, no GL.

- ``source``: frame sources: a camera device, a video file, an image sequence, memory.
- ``faces``: face detection (OpenCV's LBP frontal-face cascade, as scikit-image ships it).
- ``pose``: a face's box in the camera's image <-> the viewer's eye in the world frame.
- ``scale``: a tracked face's size from its own near view (template matching).
- ``filter``: the One-Euro filter that smooths each viewer's eye.
- ``tracker``: viewers over time: matching, hold when lost, easing to the default eye.
- ``publish``: where eyes go: ``eye``/``eyes`` lines, OSC, a player's input queue.
- ``run``: the loop from frames to publishers, and its thread for ``play --track-camera``.
- ``simwalk``: what the tracking camera sees of a face walking at known 3-D positions.
"""
