"""The BenchMARL route of `bbbench train` (the marl extra): IPPO and MAPPO on multi-bot
and team tasks, from recipes of BenchMARL's config groups (`recipes`), exported to ONNX
as they train (`train`)."""
