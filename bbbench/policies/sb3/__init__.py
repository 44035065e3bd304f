"""stable-baselines3 zips as policies, read safely: the zip and its members (`reader`,
`data`, `weights`), the table of algorithms the reader knows (`algorithms`), the numpy
actor extracted from each family (`extract`), the torch model rebuilt for training
(`rebuild`), `VecNormalize` statistics (`vecnormalize`) and the policy (`policy`)."""
