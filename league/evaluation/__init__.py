"""Playing frozen (and live) players on the fixed evaluation games: the head-to-head engine, its tables, the learning
curves measured during training and the recorded trajectories."""
