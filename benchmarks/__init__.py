"""Side-by-side benchmarks that print tables (run on demand, never in CI).

Each ``bench_*.py`` module has ``main(argv)``; ``python -m benchmarks NAME``
runs one (``python -m benchmarks`` lists them).
"""
