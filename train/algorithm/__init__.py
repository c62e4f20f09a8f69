"""The algorithm: the training config, network initialisers and networks, running
observation statistics, the trained actor, PPO (IPPO / MAPPO), and spreading environments over
devices."""
