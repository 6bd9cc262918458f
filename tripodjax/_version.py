"""The package's version, written once (pyproject.toml reads it; see CHANGELOG.md)."""

version = "0.2.0.dev0"
