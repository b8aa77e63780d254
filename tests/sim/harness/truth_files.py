"""Editing a recorded sequence's truth.csv, for the tests of files that disagree with it."""


def set_truth_cell(text: str, frame: int, column: str, value: str) -> str:
    """truth.csv's ``text`` with ``column`` of ``frame``'s row set to ``value``."""
    lines = text.splitlines()
    header = lines[0].split(",")
    cells = lines[frame + 1].split(",")
    cells[header.index(column)] = value
    lines[frame + 1] = ",".join(cells)
    return "\n".join(lines) + "\n"
