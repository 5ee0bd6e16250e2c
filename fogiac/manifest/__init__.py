"""The manifest side: the schema, YAML problems, FogROS import, the generated reference."""
