"""The built-in classical controllers (`bbbench eval pd`, `lqr`, `legged`, `crossing`,
`team`): policies computed from the observation, with no file behind them."""
