"""Scene configuration: pydantic models and TOML loading."""
