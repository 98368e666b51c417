"""The bridge's settings: broker URLs, the YAML file, and what is refused (no ROS)."""

import logging
from pathlib import Path

import pytest

from task_manager_mqtt.main import main, settings_from
from task_manager_mqtt.settings import Broker, SettingsError, Tls


def test_broker_urls() -> None:
    broker = Broker.from_url('mqtt://robot%2F1:p%40ss@broker.local')
    assert (broker.host, broker.port, broker.username, broker.password) == (
        'broker.local', 1883, 'robot/1', 'p@ss',
    )  # fmt: skip
    assert broker.tls is None and broker.url == 'mqtt://robot/1@broker.local:1883'
    secure = Broker.from_url('mqtts://10.0.0.2')
    assert (secure.port, secure.tls is not None) == (8883, True)
    for bad in ('http://host', 'mqtt://', 'mqtt://host:99999'):
        with pytest.raises(SettingsError, match='broker URL'):
            Broker.from_url(bad)
    with pytest.raises(SettingsError, match='need an mqtts:// URL'):
        Broker.from_url('mqtt://host', Tls(ca_file='ca.pem'))


def test_the_file_gives_settings_and_options_win(tmp_path: Path) -> None:
    password = tmp_path / 'password'
    password.write_text('secret\n')
    config = tmp_path / 'bridge.yaml'
    config.write_text(
        'robot_id: robot7\n'
        'broker_url: mqtts://robot7@broker.example.com\n'
        f'password_file: {password}\n'
        'tls: {ca_file: /etc/ca.pem}\n'
        'prefix: site/a\n'
    )
    settings = settings_from({'config': config, 'prefix': 'site/b'})
    assert settings.robot_id == 'robot7' and settings.prefix == 'site/b'
    assert settings.broker.password == 'secret' and settings.broker.tls is not None
    assert settings.broker.tls.ca_file == '/etc/ca.pem'


def test_the_bridge_runs_at_nice_10_unless_the_file_or_an_option_says(tmp_path: Path) -> None:
    config = tmp_path / 'bridge.yaml'
    config.write_text('robot_id: robot7\nnice: 15\n')
    assert settings_from({'robot_id': 'r'}).nice == 10
    assert settings_from({'config': config}).nice == 15
    assert settings_from({'config': config, 'nice': 0}).nice == 0


@pytest.mark.parametrize(
    ('options', 'message'),
    [
        ({}, 'robot_id is required'),
        ({'robot_id': 'a/b'}, 'one topic level'),
        ({'robot_id': 'r', 'prefix': '/x'}, 'prefix'),
        ({'robot_id': 'r', 'colour': 'red'}, "unknown settings \\['colour'\\]"),
        ({'robot_id': 'r', 'nice': 20}, 'nice 20: a whole number from 0 to 19'),
        ({'robot_id': 'r', 'nice': '5'}, "nice '5': a whole number"),
        ({'robot_id': 'r', 'nice': True}, 'nice True: a whole number'),
    ],
)
def test_unusable_settings_are_named(options: dict[str, str], message: str) -> None:
    with pytest.raises(SettingsError, match=message):
        settings_from(options)


def test_unusable_settings_exit_2_with_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['--robot-id', 'r', '--broker-url', 'tcp://host']) == 2
    error = capsys.readouterr().err
    assert error.count('\n') == 1 and 'broker URL' in error


def test_a_password_file_gives_its_trimmed_text_and_a_warning_when_others_may_read_it(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    password = tmp_path / 'password'
    password.write_text('secret\n')
    log = logging.getLogger('test_settings')
    broker = Broker.from_url('mqtt://robot1@broker.local')

    password.chmod(0o600)
    with caplog.at_level(logging.WARNING, 'test_settings'):
        kept = broker.with_password_file(password, log)
    assert (kept.username, kept.password, caplog.records) == ('robot1', 'secret', [])

    password.chmod(0o644)
    with caplog.at_level(logging.WARNING, 'test_settings'):
        broker.with_password_file(password, log)
    (record,) = caplog.records
    assert record.getMessage().startswith(f'--password-file {password} may be read by other')
    with pytest.raises(SettingsError, match='cannot read the password file'):
        broker.with_password_file(tmp_path / 'missing', log)
