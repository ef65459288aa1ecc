"""The pure-Python core of fsreg: no ROS import anywhere below this package.

One sub-package per part of the system, bottom to top (a package imports only those
before it; ``test/project/test_layers.py`` checks it):

===============  ======================================================================
``io``           reading a user's files (bounded, one-line errors), the strict YAML
                 loader, the default config paths, session recordings (rosbag2, MCAP)
``memory``       working memory: the buffer of per-entity queues and the forgetting
                 rules it runs (decay, displacement, activation), decay's tick clock
``lexicon``      realisation and the TLDL parser stub's words
``forgetting``   what is forgotten and when: the policies, the settings table, the
                 I/O-free WM Manager
``algorithms``   the paper's algorithms over the consultant port: REG (SD-PIA,
                 DIST-PIA), reference resolution, alignment
``state``        a consultant's durable state: the SQLite store, the WM journal, the
                 fact writer (group commit)
``consultant``   consultants: LTM and candidate sets, the service that serves one, its
                 persistence, views, the in-process port
``scenario``     scenario files: model, schema, checks, loading
``simulation``   the core run in one process: the simulator, ``describe`` as a
                 library call, replay of a recording, reports
===============  ======================================================================
"""
