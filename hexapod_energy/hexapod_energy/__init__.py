"""Energetic descriptors, single-leg method, inverse dynamics, sweeps, optimal operating points, residual loop; energy node."""
