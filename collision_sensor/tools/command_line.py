"""What the command-line tools share: one way to run, fail and exit.

Every tool exits 2 on an error and prints it as one line ``PROG: error: ...`` naming the culprit
(a usage error, a :class:`~collision_sensor.errors.CollisionSensorError`, an unreadable file).
"""
import sys
from typing import Callable, Optional, Sequence

from collision_sensor.errors import CollisionSensorError

EXIT_ERROR = 2


def run_command(prog: str, parser, run: Callable, argv: Optional[Sequence[str]]) -> int:
    """Parse ``argv`` with ``parser`` and return ``run(args)``, or EXIT_ERROR on an error.

    :param run: takes the parsed arguments, returns the exit status.
    """
    try:
        args = parser.parse_args(argv)
    except SystemExit as exit_request:  # --help (0) or a usage error (2, printed by argparse)
        return int(exit_request.code or 0) if not isinstance(exit_request.code, str) \
            else EXIT_ERROR
    try:
        return run(args)
    except (CollisionSensorError, OSError) as err:
        message = str(err) if isinstance(err, CollisionSensorError) else \
            f'{err.filename}: {err.strerror}' if getattr(err, 'filename', None) else str(err)
        print(f'{prog}: error: {" ".join(message.split())}', file=sys.stderr)
        return EXIT_ERROR
