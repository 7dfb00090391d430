"""League decisions: who the players are, whom a learner meets (PFSP), who won, when a phase ends.

Pure Python and NumPy: nothing here imports Ray or torch (``tests/test_layering.py``).
"""
