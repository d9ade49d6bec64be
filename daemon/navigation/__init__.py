"""One user's navigation, the same for the daemon, the simulator and the benchmark."""

from .inbox import Inbox, StepOutput
from .navigator import Navigator, NavigatorSettings, StepReport
from .outcomes import OUTCOMES, Outcome, Rejection

__all__ = [
    "OUTCOMES",
    "Inbox",
    "Navigator",
    "NavigatorSettings",
    "Outcome",
    "Rejection",
    "StepOutput",
    "StepReport",
]
