"""Studies over several runs: learning curves of seeds side by side (``curves``) and the paper's Table 1 reproduced
(``table_one``). They train runs through ``python -m league.run`` and read each run's store."""
