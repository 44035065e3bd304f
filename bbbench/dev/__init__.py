"""Maintenance tools: what the suite pins and how it is measured again.

    bbbench dev golden [--add]        # golden-rollout hashes (`bbbench.dev.golden`)
    bbbench dev random-reference      # the random policy's returns (`bbbench.dev.random_reference`)

`bbbench.dev.teams` makes the column tasks' candidates, before they are rows of the suite.

They stand above the envs and the evaluation: nothing in the package imports them.
"""
