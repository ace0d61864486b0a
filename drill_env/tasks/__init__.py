"""The control tasks of SPEC section 7, as Gymnasium envs over ``DrillString-v0``.

=========================  ============================================================
id                         the agent is ...
=========================  ============================================================
``DrillStickSlip-v0``      the top drive's stick-slip controller: a bounded correction
                           of the speed command around the driller's targets
                           (:class:`~drill_env.tasks.stick_slip.StickSlipEnv`)
``DrillOptimise-v0``       the driller: rpm and WOB set points while the bit crosses
                           formation changes (:class:`~drill_env.tasks.drilling.
                           DrillingEnv`)
=========================  ============================================================

Both subclass :class:`~drill_env.tasks.base.TaskEnv` (over :class:`~drill_env.env.
DrillStringEnv`) and keep its batch contract, so the
batched vector envs (``gymnasium.make_vec``, :func:`drill_env.vector.make_sb3_vec_env`)
run them with the physics of all envs in one compiled call.
"""

#: Task name (``drill-env train --task``, a run's ``config.yaml``) -> env id: the one map
#: that training, the shipped policies and the CLI read.
TASK_ENVS: dict[str, str] = {"stick_slip": "DrillStickSlip-v0", "drilling": "DrillOptimise-v0"}
