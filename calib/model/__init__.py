"""The runtime model (calibration -> run time contract) and its numpy reference.

- ``reference``: The numpy reference of the per-frame compensation (docs/RUNTIME.md).
"""
