"""The rule for free text that the reports show: a spec's names and text values, ``--revision``.

Imports nothing heavy: ``optimize-joint`` checks its arguments with it before JAX is imported.
"""

# A key or a text value (a name, a choice) is a label of the report's tables and figures, and
# the revision one of validation.html's (at most 4 A4 pages): at most MAX_TEXT_LENGTH
# characters; a file path at most Linux's PATH_MAX.
MAX_TEXT_LENGTH = 80
MAX_PATH_LENGTH = 4096


def length_problem(where: str, text: str, limit: int = MAX_TEXT_LENGTH) -> str | None:
    """The one line that refuses ``text`` longer than ``limit`` characters (without repeating
    it), or None."""
    if len(text) > limit:
        return f"{where} is {len(text)} characters long; at most {limit} allowed"
    return None


def label_problem(where: str, text: str) -> str | None:
    """The one line that refuses a label (a name, a revision): at most MAX_TEXT_LENGTH
    printable characters, not empty or blank; or None."""
    problem = length_problem(where, text)
    if problem is None and (not text.strip() or not text.isprintable()):
        problem = (
            f"{where} = {text!r} is not allowed: a name of printable characters, not empty or "
            "blank (no control characters such as a newline)"
        )
    return problem
