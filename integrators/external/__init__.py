"""Adapters to external libraries (scipy, numbalsoda, scikits-odes, assimulo, scikit-SUNDAE)."""
