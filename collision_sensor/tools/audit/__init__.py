"""Checking many recordings at once: ``collision_sensor_check`` with several inputs, ``--jobs``
or ``--ray`` (see :mod:`collision_sensor.tools.audit.batch`)."""
