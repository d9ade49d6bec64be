"""Chen et al.'s visibility graph with A* (seed 003): polygons, points of visibility, planner."""
