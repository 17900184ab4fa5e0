"""Errors the structure unit raises, each naming what was wrong."""


class SceneError(ValueError):
    """A scene value is malformed or out of range.

    Carries the dotted key, the offending value and what is allowed, so that the
    command line can tell the user exactly what to change before anything runs.
    """

    def __init__(self, key: str, value, allowed: str):
        self.key, self.value, self.allowed = key, value, allowed
        super().__init__(f"scene key '{key}' = {value!r}: {allowed}")


class InputError(ValueError):
    """A value crossing the unit boundary (e.g. the generalized force Q) is NaN or inf."""


class SolverDiverged(RuntimeError):
    """The state left the physical range (NaN, inf, constraint or Newton failure).

    `time` is the last time reached (s); `hint` suggests what to change.
    """

    def __init__(self, time: float, reason: str, hint: str):
        self.time, self.reason, self.hint = time, reason, hint
        super().__init__(f"diverged at t = {time:.6g} s: {reason}. Hint: {hint}")
