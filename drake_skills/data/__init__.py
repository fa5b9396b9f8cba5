"""Demonstrations: the type, file formats, LASA letters, the simulated salad scenario."""
from drake_skills.data.demonstration import MIN_SAMPLES, Demonstration

__all__ = ["Demonstration", "MIN_SAMPLES"]
