"""The core run in one process, without ROS: what the graph does, played on a model clock.

``simulator`` (a scenario's dialogue on a simulated clock, wired as the graph is),
``describe`` (generation as one library call), ``replay`` (a recording replayed turn by
turn against the model), ``replay_world`` (whether a recording matches a scenario's
world), ``report`` (tables of played scenarios).
"""
