"""Example plug-ins: one scheduler, one planner and one executor (see README.md)."""
