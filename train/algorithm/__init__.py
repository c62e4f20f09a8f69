"""The algorithm: the training config, network initialisers and networks, running
observation statistics, the trained actor and PPO (IPPO / MAPPO)."""
