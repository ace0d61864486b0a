"""The ``drill-env`` command line: the top layer over ``drill_env``, ``agents`` and
``training`` (see :mod:`drill_cli.main`)."""
