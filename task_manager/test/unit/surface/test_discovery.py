"""use_quick_discovery: the Task Manager's processes announce themselves quickly, unless the
user configures Fast DDS or another RMW."""

import xml.etree.ElementTree as ElementTree

from task_manager.discovery import PROFILE_FILE, use_quick_discovery

NAMESPACE = '{http://www.eprosima.com}'


def test_fast_dds_gets_the_profile_file() -> None:
    for rmw in ('', 'rmw_fastrtps_cpp', 'rmw_fastrtps_dynamic_cpp'):
        environ = {'RMW_IMPLEMENTATION': rmw} if rmw else {}
        assert use_quick_discovery(environ)
        assert environ['FASTDDS_DEFAULT_PROFILES_FILE'] == str(PROFILE_FILE)


def test_a_users_profile_or_another_rmw_is_left_alone() -> None:
    for environ in (
        {'FASTDDS_DEFAULT_PROFILES_FILE': '/etc/mine.xml'},
        {'FASTRTPS_DEFAULT_PROFILES_FILE': '/etc/old.xml'},
        {'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'},
    ):
        before = dict(environ)
        assert not use_quick_discovery(environ)
        assert environ == before


def test_the_profile_announces_20_times_every_50_ms_and_is_the_default() -> None:
    root = ElementTree.parse(PROFILE_FILE).getroot()
    participant = root.find(f'{NAMESPACE}profiles/{NAMESPACE}participant')
    assert participant is not None and participant.get('is_default_profile') == 'true'
    announcements = participant.find(f'.//{NAMESPACE}initialAnnouncements')
    assert announcements is not None
    assert announcements.findtext(f'{NAMESPACE}count') == '20'
    assert announcements.findtext(f'{NAMESPACE}period/{NAMESPACE}nanosec') == '50000000'


def test_the_profile_keeps_a_silent_participant_5_s_through_5_announcements() -> None:
    discovery = ElementTree.parse(PROFILE_FILE).getroot().find(f'.//{NAMESPACE}discovery_config')
    assert discovery is not None

    def seconds(element_name: str) -> float:
        element = discovery.find(f'{NAMESPACE}{element_name}')
        assert element is not None, element_name
        return float(element.findtext(f'{NAMESPACE}sec', '0')) + 1e-9 * float(
            element.findtext(f'{NAMESPACE}nanosec', '0')
        )

    assert seconds('leaseDuration') == 5.0
    assert seconds('leaseDuration') / seconds('leaseAnnouncement') == 5
