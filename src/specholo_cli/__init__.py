"""The ``specholo`` command line: a thin layer over the :mod:`specholo` library."""
