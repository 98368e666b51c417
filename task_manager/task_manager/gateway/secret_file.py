"""Files that hold a secret (the web gateway's tokens, a broker's password): whether users other
than their owner may read them, said as ssh says it of a private key."""

from pathlib import Path


def exposure_warning(path: Path) -> str | None:
    """What to say when users other than its owner may read the file at `path`; None when they
    may not."""
    mode = path.stat().st_mode & 0o777
    if not mode & 0o077:
        return None
    return (
        f'{path} may be read by other users (mode {mode:03o}): whoever reads it has its '
        f'secret; chmod 600 {path}'
    )
