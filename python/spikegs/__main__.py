"""`python -m spikegs`: the `spikegs` command (where the console script is not on PATH)."""

from .cli import console

console()
