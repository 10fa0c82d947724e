"""The run directory: the stage table, atomic artifacts, the lock and the page.

This layer imports no algorithm and no stage body (a test of the import graph keeps it so):
:mod:`~imitate.rundir.table` names the stages and what they read and write,
:mod:`~imitate.rundir.artifacts` writes files atomically and reads them with re-run hints,
:mod:`~imitate.rundir.signals` holds Ctrl-C and SIGTERM back while they are renamed into place,
:mod:`~imitate.rundir.lock` keeps one command per run directory, :mod:`~imitate.rundir.page`
renders ``report.html`` and :mod:`~imitate.rundir.schema` declares the report's keys.
"""
