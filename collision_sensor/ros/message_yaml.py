"""ROS messages to and from YAML, as ``ros2 topic echo`` prints them and ``ros2 topic pub``
takes them (ros2cli and rosidl_runtime_py are not on PyPI; this is what ``collision_sensor_ctl``
needs of them).

A message becomes a mapping of its fields in the message's order (nested messages nested,
arrays as lists, an array longer than ``truncate`` as ``'<N values>'``); a mapping fills a
message's fields by name, nested messages and arrays of messages included, and a field the
message does not have, or a value of the wrong type, is refused naming it.
"""
import importlib
from typing import Optional

import yaml

from collision_sensor.errors import ConfigError

#: Arrays and strings longer than this are shown by their length (``ros2 topic echo``'s
#: ``--truncate-length`` default).
TRUNCATE = 128


def message_type(name: str):
    """Return the message class of ``name`` (``pkg/msg/Type``, or ``pkg/Type``).

    :raises ConfigError: no such type in this Python environment.
    """
    parts = name.split('/')
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    if len(parts) != 3 or parts[1] != 'msg' or not all(parts):
        raise ConfigError(f'message type "{name}": write it as package/msg/Type, e.g. '
                          'sensor_msgs/msg/JointState')
    try:
        return getattr(importlib.import_module(f'{parts[0]}.msg'), parts[2])
    except (ImportError, AttributeError):
        raise ConfigError(f'message type "{name}" is not installed in this Python '
                          f'environment (no {parts[0]}.msg.{parts[2]}); install the package '
                          'that defines it') from None


def _is_message(value) -> bool:
    return hasattr(value, 'get_fields_and_field_types')


def to_plain(msg, truncate: Optional[int] = TRUNCATE):
    """Return ``msg`` as plain values: a dict per message, lists for arrays."""
    if _is_message(msg):
        return {name: to_plain(getattr(msg, name), truncate)
                for name in msg.get_fields_and_field_types()}
    if isinstance(msg, (bytes, bytearray)):
        msg = list(msg)
    if isinstance(msg, str):
        return msg if truncate is None or len(msg) <= truncate else \
            f'<string of {len(msg)} characters>'
    if hasattr(msg, '__len__') and not isinstance(msg, dict):
        if truncate is not None and len(msg) > truncate:
            return f'<{len(msg)} values>'
        return [to_plain(item, truncate) for item in msg]
    if hasattr(msg, 'item'):    # numpy scalars
        return msg.item()
    return msg


def message_to_yaml(msg, truncate: Optional[int] = TRUNCATE) -> str:
    """Return ``msg`` as YAML, fields in the message's order."""
    return yaml.safe_dump(to_plain(msg, truncate), sort_keys=False, default_flow_style=False,
                          width=1000)


def _element_class(msg, field: str):
    """The message class of the items of array ``field`` of ``msg`` (None: not messages)."""
    index = list(msg.get_fields_and_field_types()).index(field)
    slot = msg.SLOT_TYPES[index]
    element = getattr(slot, 'value_type', None)
    names = getattr(element, 'namespaces', None)
    if not names:
        return None
    return getattr(importlib.import_module('.'.join(names)), element.name)


def _floats(type_name: str, value):
    """``value`` with integers made floats where the field holds floats (YAML reads ``1`` as an
    integer; rclpy's float fields take floats only)."""
    base = type_name.split('<')[-1].split('[')[0].rstrip('>')
    if base not in ('double', 'float'):
        return value
    if isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if isinstance(value, list):
        return [float(v) if isinstance(v, int) and not isinstance(v, bool) else v
                for v in value]
    return value


def fill_message(msg, values, where: str = 'message'):
    """Set ``msg``'s fields from ``values`` (a mapping, as ``ros2 topic pub`` takes it); return
    ``msg``.

    :raises ConfigError: a field ``msg`` does not have, or a value it cannot take, named with
        its path (``points[2].positions``).
    """
    if not isinstance(values, dict):
        raise ConfigError(f'{where}: expected a mapping of fields, got {type(values).__name__}')
    fields = msg.get_fields_and_field_types()
    for name, value in values.items():
        path = f'{where}.{name}' if where != 'message' else name
        if name not in fields:
            raise ConfigError(f'{path}: {type(msg).__name__} has no field "{name}" (it has '
                              f'{", ".join(fields)})')
        current = getattr(msg, name)
        try:
            if _is_message(current):
                fill_message(current, value, path)
                continue
            if isinstance(value, str) and ('sequence<' in fields[name] or
                                           fields[name].endswith(']')):
                raise ConfigError(f'{path}: {value!r} is one string; the field is a list '
                                  f'({fields[name]}): write [{value}]')
            element = _element_class(msg, name)
            if element is not None:
                if not isinstance(value, list):
                    raise ConfigError(f'{path}: expected a list of {element.__name__}')
                value = [fill_message(element(), item, f'{path}[{k}]')
                         for k, item in enumerate(value)]
            setattr(msg, name, _floats(fields[name], value))
        except (AssertionError, TypeError, ValueError) as error:
            raise ConfigError(f'{path}: {value!r} does not fit field type {fields[name]} '
                              f'({error})') from None
    return msg
