"""Self-tests an operator runs with the instrument: the units-and-signs press test."""

from ._press import PRESS_PROTOCOL, PressStep, PressTestResult, StepCheck, check_press_test

__all__ = ["PRESS_PROTOCOL", "PressStep", "PressTestResult", "StepCheck", "check_press_test"]
