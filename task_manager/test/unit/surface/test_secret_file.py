"""A file holding a secret that users other than its owner may read is named, with its mode
and the command that mends it."""

from pathlib import Path

import pytest

from task_manager.gateway.secret_file import exposure_warning


@pytest.mark.parametrize('mode', [0o644, 0o640, 0o604, 0o660])
def test_a_file_others_may_read_gets_a_warning_that_says_how_to_mend_it(
    tmp_path: Path, mode: int
) -> None:
    secret = tmp_path / 'secret'
    secret.write_text('s3cret\n')
    secret.chmod(mode)

    warning = exposure_warning(secret)

    assert warning is not None
    assert f'(mode {mode:03o})' in warning and warning.endswith(f'chmod 600 {secret}')
    assert 's3cret' not in warning


@pytest.mark.parametrize('mode', [0o600, 0o400])
def test_a_file_only_its_owner_may_read_gets_no_warning(tmp_path: Path, mode: int) -> None:
    secret = tmp_path / 'secret'
    secret.write_text('s3cret\n')
    secret.chmod(mode)

    assert exposure_warning(secret) is None
