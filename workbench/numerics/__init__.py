"""The numerical core, pure arrays in and out: the bases (PCA, quasi-eigen), the weight solvers, alpha and the
other metrics, the alternative bases and the estimator that wraps them for plain arrays."""
