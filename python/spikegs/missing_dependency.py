"""The error for an optional dependency (an extra) that is needed and not installed."""


class MissingDependencyError(ImportError):
    """An optional dependency (an extra) is needed and not installed; the message says how to
    install it. `spikegs` commands report it as an error (exit status 2)."""
