"""Running the ``optimize-joint`` command in a fresh process, as a user does."""

import os
import subprocess
import sys

COMMAND = [
    sys.executable,
    "-P",  # the installed package, not the source folders of the repository root
    "-c",
    "from tripodjax.optimize.cli import command; command()",
]


def run_cli(*args, cwd=None, cache=None):
    """``optimize-joint ARGS`` in a new process: its completed process (text output).

    The command caches compiled code: in the run's cache (conftest) unless ``cache`` is given."""
    env = dict(os.environ, **({"TRIPODJAX_CACHE_DIR": str(cache)} if cache else {}))
    return subprocess.run(
        [*COMMAND, *args], capture_output=True, text=True, timeout=900, cwd=cwd, env=env
    )
