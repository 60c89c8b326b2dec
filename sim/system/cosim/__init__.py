"""Co-simulation of the firmware (host shared library) with the RTL, see run.py."""
