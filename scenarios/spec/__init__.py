"""The scenario file: its pydantic models, --set overrides, the JSON Schema and the library of TOML files."""
