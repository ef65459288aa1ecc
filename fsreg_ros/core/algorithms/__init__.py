"""The paper's algorithms, over the consultant port.

``port`` (:class:`~.port.ConsultantPort`: what RR and REG may ask of a consultant, the
incremental walk's rules, :class:`~.port.KnowledgeError`), ``generation`` (REG: SD-PIA,
DIST-PIA and two baselines; Algorithm 4 and the Incremental Algorithm),
``resolution`` (reference resolution), ``alignment`` (how far the robot's descriptions
reuse the human's words).  Nothing here knows where a consultant runs.
"""
