"""What each domain forgets, and when: the rules' policy, their settings, the WM Manager.

``policies`` (:class:`~.policies.ForgettingPolicy`: ``none`` or rules joined by ``+``,
parsed and turned into buffer limits), ``settings`` (the memory settings table, every
setting declared once), ``presets`` (named settings and REG's WM order for a
builder: ``human-like``, ``paper``), ``wm_manager`` (the I/O-free WM Manager: decay schedules, the
shared pool, clocks sent to the buffers), ``keeps`` (what each rule is sure to keep within a
stretch of dialogue: a replay over a grid of settings skips what cannot change).  The buffers that enforce a policy are
:mod:`fsreg_ros.core.memory`, below this package.
"""
