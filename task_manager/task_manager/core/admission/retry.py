"""A declaration's retries: how many attempts, the backoff between them, which errors."""

from dataclasses import dataclass

from task_manager.core.status import ErrorCode

SERVER_ERROR = 'aborted'
"""In on_error_codes: an ERROR its server gave (the goal aborted), which has no error code."""


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
        delay = self.initial_delay_sec * self.multiplier ** (attempt - 1)
        return min(delay, self.max_delay_sec)


NO_RETRY = RetryPolicy()
