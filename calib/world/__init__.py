"""The physical set-up: rig.toml, eye positions, screen geometry, camera responses.

- ``audience``: An audience: several viewers at once, each an eye position with a weight.
- ``eye``: Eye positions: a viewing angle is a shorthand for an eye position (docs/MODEL.md
  section 1).
- ``geometry``: Screen geometry on the projector's pixel grid (docs/MODEL.md section 1), and the
  one ray/plane intersection.
- ``lens``: Lens distortion: OpenCV's model on normalised image coordinates.
- ``response``: Camera response curves: encoded pixel value <-> linear light.
- ``rig``: The rig: projector, camera, viewer and capture settings of rig.toml
  (docs/INTERFACES.md).
"""
