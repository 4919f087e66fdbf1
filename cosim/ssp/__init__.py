"""SSP 1.0 packages: reading one into scene data (read) and writing a scene as one (export)."""
