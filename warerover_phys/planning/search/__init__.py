"""Space-time searches: prioritized A* (:mod:`.astar`), windowed CBS (:mod:`.cbs`), A* with
headings (:mod:`.turning_astar`) and the open list they share (:mod:`.frontier`)."""
