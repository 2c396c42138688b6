"""Scripts that rebuild the data files shipped with the package (run with ``python -m``)."""
