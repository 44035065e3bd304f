"""The stable-baselines3 route of `bbbench train`: rl-zoo3 recipes (`recipes`), the
training loop (`train`) and its evaluation on training seeds (`callbacks`)."""
