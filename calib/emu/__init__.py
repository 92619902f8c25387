"""A hardware emulator harsher than the simulator: a DLP projector and real cameras' flaws.

It implements the device protocols of :mod:`viewcomp.calib.hw.interface` (Camera,
Projector, Clock) over the simulator's world, so the real capture procedure runs against it
unchanged:

- :mod:`~viewcomp.calib.emu.clock`: emulated time that devices advance as hardware would;
- :mod:`~viewcomp.calib.emu.dlp`: a DLP's colour sub-frames, PWM bit planes and response,
  integrated exactly over any exposure window;
- :mod:`~viewcomp.calib.emu.projector`: vsync'd swaps, a latency of 2..4 refreshes;
- :mod:`~viewcomp.calib.emu.profiles` and :mod:`~viewcomp.calib.emu.camera`: a UVC webcam
  (MJPEG, driver queue, auto exposure and white balance, rolling shutter, tone curve,
  Bayer), a DSLR (slow, raw 14-bit) and a mono 12-bit machine-vision camera;
- :mod:`~viewcomp.calib.emu.scene`: the simulator's physics on a supersampled camera grid;
- :mod:`~viewcomp.calib.emu.faults`: bumps, dropped frames, failed reads, late frames;
- :mod:`~viewcomp.calib.emu.emulator`: :func:`open_emulator`, the rig and its truth.
"""
