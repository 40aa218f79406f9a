"""Problems from other formats, read into a :class:`~warerover_phys.config.Scenario` of the
one loop (:mod:`warerover_phys.sim`): League of Robot Runners problems
(:mod:`.robotrunners`). A MovingAI map with a task stream needs no reader: it is a scenario
with ``layout.map`` and ``orders.pattern: errands``."""
