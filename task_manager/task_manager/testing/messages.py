"""A type for the message classes rosidl generates, whose modules carry no type hints."""

from typing import ClassVar, Protocol

from rosidl_parser import definition as idl


class GeneratedMessage(Protocol):
    """The class-level introspection every generated message class has."""

    SLOT_TYPES: ClassVar[tuple[idl.AbstractType, ...]]
    """The field types, in declaration order."""

    @classmethod
    def get_fields_and_field_types(cls) -> dict[str, str]:
        """key: field name, value: its rosidl type (e.g. 'sequence<int32, 3>'), in order."""
        ...
