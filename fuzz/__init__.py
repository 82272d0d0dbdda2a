"""Coverage-guided fuzz targets for edge-vis's parsers (run with atheris)."""
