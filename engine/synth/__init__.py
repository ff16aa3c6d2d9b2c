"""Procedural two-person-and-object scenes with exact phase and contact labels.

`synthesize(scenario, seed)` gives one MotionClip; `write_dataset` writes many plus an index.
See scenarios.py for what each scenario shows.
"""
from .assemble import SynthConfig, synthesize
from .scenarios import SCENARIOS
from .writer import write_dataset

__all__ = ["SCENARIOS", "SynthConfig", "synthesize", "write_dataset"]
