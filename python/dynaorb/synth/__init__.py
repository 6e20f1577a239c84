"""Synthetic dynamic sequences with exact ground truth (`dynaorb synth`)."""

from dynaorb.synth.generate import SENSORS, SynthConfig, generate

__all__ = ["SENSORS", "SynthConfig", "generate"]
