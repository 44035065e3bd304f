"""ONNX models as policies, from any framework: the file read safely (`reader`), its
contract (`contract`), the operators and their interpreter that run it with portable
arithmetic (`operators`, `interpreter`), the policy (`policy`) and the exporter
(`export`)."""
