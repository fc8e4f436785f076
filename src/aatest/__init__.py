"""aatest: calibrate angular accelerometers on turntables."""

__version__ = "0.1.0"
