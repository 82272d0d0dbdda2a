"""End-to-end tests of the relay; DDS fixtures are in ``tests/conftest.py``."""

try:
    import cyclonedds  # noqa: F401
except ImportError:  # Cyclone DDS is not installed: nothing here can run
    collect_ignore_glob = ["test_*.py"]
