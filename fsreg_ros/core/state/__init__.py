"""A consultant's durable state: what survives a restart.

``store`` (one SQLite database per consultant, WAL mode, locked by one process: facts,
WM checkpoints and journal), ``journal`` (WM operations as redo records and their
replay), ``fact_writer`` (LTM facts committed off the serving thread, group commit).
How a serving consultant uses them is :mod:`fsreg_ros.core.consultant.persistence`.
"""
