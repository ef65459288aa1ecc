"""Consultants (DIARC's pattern): one per knowledge domain, owning its LTM and its WM.

``consultant`` (:class:`~.consultant.Consultant`: LTM, candidate sets, the encodings
queries make; ``holders``: LTM's per-property holder bitsets), ``service``
(:class:`~.service.ConsultantService`: one call = one op, its changes, one commit;
``fact_batches``: LTM facts checked, stored and applied in batches), ``ops`` (each op
of the consultant protocol as one typed call on the service: its session, request
time, clock notes), ``persistence`` (restore at start, clock epochs, checkpoints),
``views`` (open RR/REG candidate sets, bounded), ``local_port`` (the port in-process).
"""
