"""The paper's Section 5 in the simulator: protocols, metrics, test images, report.

- ``evaluate``: The paper's Section 5 in the simulator (docs/MODEL.md section 5): table2, sweep,
  oracle.
- ``metrics``: Image error measures for the evaluation (docs/MODEL.md section 5).
- ``preview``: What the audience will see: the calibration's forward prediction, side by side
  (``viewcomp preview``, the demo's pictures).
- ``report``: Writing the evaluation's report: report.json, report.md and PNG plots.
- ``run``: ``viewcomp evaluate``: run the protocols and write the report.
- ``testimages``: Test images for the evaluation: natural photographs and uniform colours.
"""
