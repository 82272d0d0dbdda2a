"""Tests of the DDS side; the fixtures (loopback Cyclone, domain ids, bridges) are in
``tests/conftest.py``."""

try:
    import cyclonedds  # noqa: F401
except ImportError:  # Cyclone DDS is not installed: only the IDL command tests can run
    collect_ignore_glob = ["test_[!i]*.py", "test_idl_model.py"]
