"""The argument parser of every command (``python -m tripodjax``, ``optimize-joint``, the benches).

A bad argument is one line naming it, its value and what is allowed, and exit status 2
(argparse's own parser prints its usage block first). Imports nothing heavy: a command's
``--help`` and argument errors answer before JAX is imported.
"""

import argparse

EXIT_BAD_INPUT = 2


class ArgumentParser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` whose error is one line, then exit status 2."""

    def error(self, message):  # one line, no usage block
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: {message} (see --help)\n")
