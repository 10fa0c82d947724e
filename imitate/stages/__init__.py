"""The stages of a run, one module each (``observe``, ``learn``, ``optimize``, ``replay``,
``figures``: a ``run(run_dir, config) -> report sections`` function), the run's settings
(:mod:`~imitate.stages.config`), the inputs' provenance (:mod:`~imitate.stages.provenance`) and
the runner that commits a stage all or nothing (:mod:`~imitate.stages.runner`)."""
