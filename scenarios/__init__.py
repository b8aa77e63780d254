"""Shipped scenario files (TOML); see sim.harness.scenario for their keys and defaults."""

from pathlib import Path

#: Folder of the shipped ``*.toml`` scenarios.
SCENARIOS_DIR = Path(__file__).resolve().parent

#: The scenario ``egostab run`` walks when none is named.
DEFAULT_SCENARIO = "corridor_straight"

#: Folder of the shipped suites (``egostab suite``; docs/suites.md).
SUITES_DIR = SCENARIOS_DIR / "suites"
