"""viewcomp: view-dependent radiometric compensation for projectors.

``viewcomp.calib`` (numpy, no GL) turns captures into a calibration bundle and holds the
numpy reference of the per-frame formula; ``viewcomp.rt`` renders it with OpenGL;
``viewcomp.shaders`` holds the GLSL files.
"""

__version__ = "0.1.0"
