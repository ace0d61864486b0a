"""The ``drill-env`` command line: the top layer over ``drill_env``, ``agents`` and
``training``. :mod:`drill_cli.main` runs a command (its errors, signals and exit status),
:mod:`drill_cli.parser` defines every command's options, and each command lives in a
module of its own: :mod:`~drill_cli.run` (``demo``, ``run``), :mod:`~drill_cli.benchmark`,
:mod:`~drill_cli.train` (``train``, ``evaluate``), :mod:`~drill_cli.studies`
(``stability-map``, ``modes``, ``well``) and :mod:`~drill_cli.tools` (``speed``,
``replay``), over the shared :mod:`~drill_cli.arguments` and :mod:`~drill_cli.configs`."""
