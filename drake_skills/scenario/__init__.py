"""Scenarios: simulated people and the robot's demonstrations in a scene of ``sim/`` (the salad scenario)."""
