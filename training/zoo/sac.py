"""rl-zoo3 SAC hyperparameters (``--conf-file training.zoo.sac``)."""

from training.zoo import zoo_hyperparams

hyperparams = zoo_hyperparams("sac")
