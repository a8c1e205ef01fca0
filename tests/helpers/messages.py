"""Reading a message the way a user does: what it names, not its wording."""


def says(message: str, *facts: str) -> bool:
    """True when ``message`` is one line that holds every one of ``facts`` (a path, a flag, a row, a
    number, the cause in a word), whatever sentence is written around them."""
    text = str(message).strip()
    return "\n" not in text and all(str(f) in text for f in facts)
