"""Progress lines a person can follow on long stages: "label: k/n done, elapsed, about m min left"
through the logging system (so they reach the rule's log file and the console alike)."""
from __future__ import annotations

import logging
import time


class Progress:
    """Counts finished units of work (scans registered, frequency steps solved, ...) and logs each with
    the elapsed time and an estimate of the time left (mean time per unit so far x units left)."""

    def __init__(self, total: int, label: str, logger: logging.Logger, clock=time.perf_counter) -> None:
        self.total, self.label, self.logger, self.clock = int(total), label, logger, clock
        self.done = 0
        self.started = clock()

    def seconds_left(self) -> float | None:
        """Estimated seconds until every unit is done; None before the first one finished."""
        if self.done == 0:
            return None
        return (self.clock() - self.started) / self.done * (self.total - self.done)

    def step(self, what: str = "", units: int = 1) -> str:
        """Mark ``units`` more as done and log (and return) the progress line."""
        self.done += units
        elapsed = self.clock() - self.started
        left = self.seconds_left()
        line = (f"{self.label}: {self.done}/{self.total} done" + (f" ({what})" if what else "")
                + f", {elapsed / 60:.1f} min elapsed" + (f", about {left / 60:.1f} min left" if left else ""))
        self.logger.info(line)
        return line
