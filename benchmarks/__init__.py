"""The benchmarks: collision_sensor against pinocchio+coal and python-fcl, measured in one run.

Not part of the installed package (setup.py ships ``collision_sensor`` only): they import the
peers (python-fcl, pinocchio, coal: the ``test`` extra) and run from a source checkout, with
the package installed (``make`` installs it editable into ``.venv``)::

    python -m benchmarks [--quick] [--scenario N ...] [--runs N] [--markdown FILE]   # make bench
    python -m benchmarks audit [--recordings N] ...    # checking many recordings
    python -m benchmarks.node_latency [--rate HZ,...]   # the running node, end to end
    python -m benchmarks.fuzz [--messages N]            # the running node against bad input

and the parts on their own: ``python -m benchmarks.<name>`` (``robot_peers``, ``fk``,
``box_tests``, ``acm_rate``, ``first_start``). They print timings and ratios;
they are not tests and assert nothing. They use the package's public API only.
"""
