"""The RLlib adapter: the only package that imports ``ray.rllib`` (``tests/test_layering.py``).

The rest of the code goes through one module, ``league.rllib.bridge`` (build the algorithm,
hand it match plans, move weights, read ``train()`` results, load checkpoints); the other
modules are what RLlib is subclassed or fed with: the algorithm and its learner, the env
runner, the RLModules, the loss, and ``compat``, the one home of RLlib's private attributes.
"""
