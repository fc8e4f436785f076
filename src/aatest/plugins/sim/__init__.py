"""The digital twin of the rig, shared by the simulated turntable, DAQ and chamber plugins."""
