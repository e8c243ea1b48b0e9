"""Planning: color order, travel order, purge towers, look-ahead of state changes."""
