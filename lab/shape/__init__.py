"""The OP-PV shape network's room (issue 36): its corpus of simulated loops and their
linear-valve twins (draws, valves, loads, historian, simulate, corpus), its data, training
(net, train: PyTorch, the bench extra), the research table and the confidence methods
(research, confidence, metrics) and the export to stiction/diagnosis/shape.npz (export).
lab/shape/README.md holds every figure."""
