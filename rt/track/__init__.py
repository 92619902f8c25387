"""Following the audience with a camera (`viewcomp track`): OpenCV and numpy, no GL.

- ``source``: frame sources: a camera device, a video file, an image sequence, memory.
- ``yunet``: faces and their landmarks (YuNet, the model shipped in ``models/``, checksummed);
  tracked faces followed in crops.
- ``live_faces``: YuNet for a live camera: each frame at half resolution and one tile (or
  where it changed) at full.
- ``changes``: where a live frame changed, away from the faces known: searched first.
- ``refusals``: where a second look (or a search where the frame changed) found no face,
  looked at less and less often.
- ``rectify``: a face seen square-on: a crop of a frame as a virtual camera pointed at it.
- ``noise``: how noisy a face's picture is, and how much its refinement crop is smoothed.
- ``boxes``: how much two face boxes overlap.
- ``anatomy``: a viewer's eye from the landmarks: distance from the interpupillary distance,
  corrected for the head's turn; a viewer's face height and the range it gives a turned face.
- ``faces``: the fallback detector (OpenCV's LBP cascade, as scikit-image ships it).
- ``pose``: the fallback's ranging: a face's box <-> the viewer's eye (box-size convention).
- ``scale``: the fallback's face size from its own near view (template matching).
- ``filter``: the One-Euro filter that smooths each viewer's eye.
- ``tracker``: viewers over time: matching, each viewer's face height, hold when lost,
  easing to the default eye.
- ``publish``: where eyes go: ``eye``/``eyes`` lines, OSC, a player's input queue.
- ``run``: the loop from frames to publishers, and its thread for ``play --track-camera``.
- ``simscene``: photographs of people drawn as 2.5-D heads placed by their eyes, seen by an
  ideal camera or the emulated webcam (tests).
- ``simrelief``: the surfaces a photograph is painted on: a model (cylinder and nose ridge)
  or a scanned face's measured relief (tests).
- ``simscan``: a head scanned in 3-D (a textured mesh) placed by its eyes the same way
  (tests).
- ``simwalk``: what the tracking camera sees of a face walking at known 3-D positions.
- ``simtrack``: that walk tracked by the pipeline, beside its truth.
"""
