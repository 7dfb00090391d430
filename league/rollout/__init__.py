"""The Ray-free rollout: N games stepped as arrays by module (``games``), and the rows it yields made training data
(``train_batch``: GAE, shaping, minibatches). Used by the RLlib env runner and by evaluation alike."""
