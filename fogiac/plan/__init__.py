"""The plan side: the typed Plan, compile, the instance catalog, cost, saved plans, the diagram."""
