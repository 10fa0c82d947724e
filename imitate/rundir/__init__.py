"""The run directory: its files, atomic artifacts, the lock and the page.

This layer imports nothing of imitate but its errors (a test of the import graph keeps it so):
:mod:`~imitate.rundir.layout` names the files of a run directory,
:mod:`~imitate.rundir.artifacts` writes files atomically and reads them with errors that name
them, :mod:`~imitate.rundir.signals` holds Ctrl-C and SIGTERM back while they are renamed into
place, :mod:`~imitate.rundir.lock` keeps one command per run directory,
:mod:`~imitate.rundir.page` renders ``report.html`` and :mod:`~imitate.rundir.schema` declares
the report's keys. Which stage writes which file is :mod:`imitate.stages.table`'s; what each
file holds, :mod:`imitate.stages.files`'.
"""
