"""The argument parser of every command (``python -m tripodjax``, ``optimize-joint``, the benches).

A bad argument is one line naming it, its value and what is allowed, and exit status 2
(argparse's own parser prints its usage block first). Imports nothing heavy: a command's
``--help`` and argument errors answer before JAX is imported.
"""

import argparse
import json
import os
import sys
import tempfile

EXIT_BAD_INPUT = 2


class ArgumentParser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` whose error is one line, then exit status 2."""

    def error(self, message):  # one line, no usage block
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: {message} (see --help)\n")


def count(minimum, multiple=1):
    """An argparse type: an integer ≥ ``minimum`` (and a multiple of ``multiple``), else the
    parser's one-line error naming the value and what is allowed."""
    rule = f"an integer ≥ {minimum}" + (f", a multiple of {multiple}" if multiple > 1 else "")

    def parse(text):
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < minimum or value % multiple:
            raise argparse.ArgumentTypeError(f"{text!r} is not allowed; allowed: {rule}")
        return value

    return parse


def counts(text):
    """An argparse type: comma-separated integers ≥ 1 (empty: none)."""
    return [count(1)(part) for part in text.split(",") if part]


def output_file(text):
    """An argparse type: a file to write, in a folder that exists and can be written to; else
    the parser's one-line error, before anything is computed."""
    folder = os.path.dirname(os.path.abspath(text)) if text else ""
    if not text or os.path.isdir(text):
        problem = "it is a folder" if text else "it is empty"
    elif not os.path.isdir(folder):
        problem = f"the folder {folder} does not exist"
    elif not os.access(folder, os.W_OK | os.X_OK):
        problem = f"the folder {folder} cannot be written to"
    else:
        return text
    raise argparse.ArgumentTypeError(
        f"{text!r} is not allowed ({problem}); allowed: a file in a folder that can be written to"
    )


def write_text(path, text):
    """Write ``text`` to ``path`` atomically (a temporary file renamed into place); OSError if it
    cannot be written, and then nothing is left."""
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=f".{os.path.basename(path)}.", dir=folder)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600 files
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def write_json(prog, path, figures):
    """A bench's ``figures`` as JSON in ``path`` (``write_text``); a failure is one line on
    stderr and False."""
    try:
        write_text(path, json.dumps(figures, indent=2))
    except OSError as error:
        print(f"{prog}: cannot write {path}: {error.strerror or error}", file=sys.stderr)
        return False
    return True


EXIT_BROKEN_PIPE = 141  # 128 + SIGPIPE, as a shell reports a writer whose reader left


def finish(main, *args):
    """``main(*args)``'s exit status; a reader that closed the pipe early (``| head``) ends the
    command quietly with ``EXIT_BROKEN_PIPE`` instead of a traceback."""
    try:
        code = main(*args)
        sys.stdout.flush()
    except BrokenPipeError:
        # Python flushes stdout again at exit: point it at /dev/null first (Python's docs).
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        code = EXIT_BROKEN_PIPE
    return code
