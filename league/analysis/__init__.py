"""Numbers read off recorded results: the meta-game's Nash equilibrium, exploitability from best responses,
progress over generations, and the statistics (intervals) they share. Reads; plays no game."""
