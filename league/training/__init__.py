"""Training a league: the coordinator's loop over iterations and phases, best responses, progress output and stop
requests. Drives the RLlib adapter (``league.rllib.bridge``) and writes the store."""
