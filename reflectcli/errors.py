"""User-facing errors: one line each, naming the file and the field."""

from __future__ import annotations


class Problem(Exception):
    """One problem with the input: `file: field: message`."""

    def __init__(self, file: str, field: str, message: str) -> None:
        super().__init__(f"{file}: {field}: {message}" if field else f"{file}: {message}")
        self.file, self.field, self.message = file, field, message

    def __reduce__(self):  # picklable, so a bench worker process can send it back
        return (Problem, (self.file, self.field, self.message))


class Problems(Exception):
    """Several problems found together (validation reports them all at once)."""

    def __init__(self, problems: list[Problem]) -> None:
        super().__init__("\n".join(str(p) for p in problems))
        self.problems = problems

    def __reduce__(self):
        return (Problems, (self.problems,))
