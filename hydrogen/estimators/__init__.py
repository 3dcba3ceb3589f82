"""The loop's estimators, one module each: what the estimate stage computes from the measurements
besides the pose (:mod:`hydrogen.estimators.kalman`: the fixed-gain Kalman filter on each actuator's
travel). An estimator module holds its design (gains from the scenario's settings), its update over
numpy (the Python engine, :class:`hydrogen.simulation.simulator.PythonStages`) and the same update's C
statements (rendered into the loop driver, ``templates/loop.c.j2``), side by side in one place."""
