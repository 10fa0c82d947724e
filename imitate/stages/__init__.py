"""The stages of a run, one module each (``observe``, ``learn``, ``optimize``, ``replay``,
``figures``: a ``run(run_dir, config) -> report sections`` function), named in order with what
they read and write by :mod:`~imitate.stages.table`; the run files they write and read, one class
each (:mod:`~imitate.stages.files`: the library below reads and writes no file of a run), the
run's settings (:mod:`~imitate.stages.config`), the inputs' provenance
(:mod:`~imitate.stages.provenance`) and the runner that commits a stage all or nothing
(:mod:`~imitate.stages.runner`)."""
