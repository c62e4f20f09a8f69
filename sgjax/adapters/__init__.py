"""Layer 5, adapters to other libraries: PettingZoo (``pettingzoo``), Stable-Baselines3
(``sb3``) and JaxMARL (``jaxmarl``)."""
