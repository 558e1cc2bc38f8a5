"""The scripts that make pedmesh's shipped data, and the validation runs they fit to.

Each module is a script, run from a source checkout (it reads ``geometries/experiments/``
and writes into ``pedmesh/data/`` and ``docs/validation/``)::

    python -m pedmesh.fitting.validate       # the SFM against the Juelich experiments
    python -m pedmesh.fitting.fit_validated  # fits the validated preset (hours)
    python -m pedmesh.fitting.continuum_law  # the continuum models' table (2 minutes)
    python -m pedmesh.fitting.after_fit      # everything a refit makes stale (hours)

* :mod:`pedmesh.fitting.validate` simulates the Juelich corridor runs, a bottleneck series
  and free walking, and measures simulation and experiment alike
  (:mod:`pedmesh.validation`, PedPy). It writes the tables of ``docs/validation/*/``, and
  its :func:`~pedmesh.fitting.validate.run_validation` is the fit's objective.
* :mod:`pedmesh.fitting.fit_validated` fits the ``validated`` preset's social force
  parameters to those runs. It writes ``pedmesh/data/validated.json`` and
  ``docs/validation/fit.md``, and logs every evaluation to ``docs/validation/*.csv``.
* :mod:`pedmesh.fitting.after_fit` runs what follows a refit, in order and resumable: the
  continuum's table and equation of state, the convergence study, the door probes, the
  validation tables, eos against the SFM, RiMEA and the docs' figures.
* :mod:`pedmesh.fitting.continuum_law` measures the fitted social force model's fundamental
  diagram. The result, ``pedmesh/data/fd_validated.json``, is the continuum models' speed
  table under the preset.

The rest of ``pedmesh/data/`` is made elsewhere. The equations of state
``eos_default.json`` (Table 1) and ``eos_validated.json`` (the validated preset's social
force parameters) come from ``pedmesh calibrate``; each file records its parameters and
options. ``bottleneck_literature.json`` holds published flows, typed in by hand.

``--help`` on each script lists its options. Nothing else in pedmesh imports this package.
"""
