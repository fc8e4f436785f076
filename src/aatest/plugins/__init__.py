"""Plugins: rig drivers (turntable, daq, chamber, sensors), the digital twin they share (sim),
synchronisation, analyses and reports. Each kind has its own sub-package."""
