"""Hydra configs of bbbench's BenchMARL tasks (conf/task/bbbench/*.yaml), found as pkg://bbbench.marl.conf."""
