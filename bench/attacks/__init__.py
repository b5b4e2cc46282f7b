"""The red team's benchmarks: each attack on the baseline commit's gateway and on this
tree's, side by side."""
