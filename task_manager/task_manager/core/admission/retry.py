"""A declaration's retries: how many attempts, the backoff between them, which errors."""

import math
from dataclasses import dataclass

from task_manager.core.bounds import SECONDS
from task_manager.core.status import ErrorCode

SERVER_ERROR = 'aborted'
"""In on_error_codes: an ERROR its server gave (the goal aborted), which has no error code."""
RETRYABLE_ERROR_CODES = (SERVER_ERROR, ErrorCode.TASK_START_FAILED.value, ErrorCode.TIMEOUT.value)
"""What on_error_codes may name: the ways a started or starting task ends ERROR."""


@dataclass(frozen=True)
class RetryPolicy:
    """Attempts after an ERROR end, with exponential backoff; one attempt means no retry."""

    max_attempts: int = 1
    initial_delay_sec: float = 1.0
    multiplier: float = 2.0
    max_delay_sec: float = 60.0
    on_error_codes: tuple[str, ...] = ()
    """Error codes worth another attempt (SERVER_ERROR for a server's own failure); empty: any."""

    def retries(self, attempt: int, error_code: ErrorCode) -> bool:
        """Whether an attempt that ended ERROR with `error_code` is followed by another."""
        if attempt >= self.max_attempts:
            return False
        if not self.on_error_codes:
            return True
        return (str(error_code) or SERVER_ERROR) in self.on_error_codes

    def delay_sec(self, attempt: int) -> float:
        """The wait before attempt `attempt + 1`, after attempt `attempt` (1 first) failed."""
        if self.initial_delay_sec == 0:
            return 0.0
        try:
            delay = self.initial_delay_sec * self.multiplier ** (attempt - 1)
        except OverflowError:  # a float power past 1e308: far beyond any cap
            return self.max_delay_sec
        return min(delay, self.max_delay_sec)

    def problem(self) -> str:
        """Why this policy is unusable, starting with the field's name; empty when it is fine."""
        if self.max_attempts < 1:
            return f'max_attempts must be >= 1 (1: no retry), got {self.max_attempts!r}'
        for name in ('initial_delay_sec', 'max_delay_sec'):
            if problem := SECONDS.problem(name, getattr(self, name)):
                return problem
        if not 1 <= self.multiplier < math.inf:
            return f'multiplier must be a finite number >= 1, got {self.multiplier!r}'
        for code in self.on_error_codes:
            if code not in RETRYABLE_ERROR_CODES:
                allowed = ', '.join(RETRYABLE_ERROR_CODES)
                return f'on_error_codes must name some of {allowed}, got {code!r}'
        return ''


NO_RETRY = RetryPolicy()
