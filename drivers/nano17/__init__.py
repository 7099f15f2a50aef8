"""The ATI Nano17: calibration files and the DAQ layer that turns gauge voltages into forces."""
