"""Developer and study tools on top of the env layer: the speed benchmark
(``drill-env speed``), the paper studies and the demo. Nothing here is needed to train
or run an env."""
