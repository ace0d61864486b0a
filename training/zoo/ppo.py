"""rl-zoo3 PPO hyperparameters (``--conf-file training.zoo.ppo``)."""

from training.zoo import zoo_hyperparams

hyperparams = zoo_hyperparams("ppo")
