"""Expression compiler: compile time, and evaluation at 10^6 points against plain numpy.

Run: ``.venv/bin/python benchmarks/bench_expressions.py``. Prints the median of several
runs in ms and the ratio to the same formula written directly in numpy.
"""

import statistics
import time

import numpy as np

from fgslice.design.expressions import compile_expression

N = 1_000_000
CASES = [
    (
        "(1+sin(0.025*x+0.0375*y)*cos(0.0375*x-0.025*y))/2",
        lambda x, y, z: (1 + np.sin(0.025 * x + 0.0375 * y) * np.cos(0.0375 * x - 0.025 * y)) / 2,
    ),
    ("(1+(0.025*x+0.0375*y)*(0.0375*x-0.025*y))/2", lambda x, y, z: (1 + (0.025 * x + 0.0375 * y) * (0.0375 * x - 0.025 * y)) / 2),
    ("(rho-15)/35", lambda x, y, z: (np.hypot(x, y) - 15) / 35),
    ("abs(phi)/pi", lambda x, y, z: np.abs(np.arctan2(y, x)) / np.pi),
    ("z/70", lambda x, y, z: np.broadcast_to(z / 70, x.shape).copy()),
    # OpenVCAD 3 (ExprTk) forms: a local, and a switch
    ("var t := x/3 + 236; clamp(220, t, 256)", lambda x, y, z: np.clip(x / 3 + 236, 220, 256)),
    (
        "switch { case x < -20: 0.2; case x > 20: 0.8; default: 0.5 + x / 100; }",
        lambda x, y, z: np.select([x < -20, x > 20], [0.2, 0.8], 0.5 + x / 100),
    ),
]


def median_ms(fn, repeat=7):
    fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e3 * statistics.median(times)


def main():
    rng = np.random.default_rng(0)
    x = rng.uniform(-100, 100, N)
    y = rng.uniform(-100, 100, N)
    z = rng.uniform(0, 70, N)
    print(f"{'expression':55s} {'compile ms':>10s} {'eval ms':>9s} {'numpy ms':>9s} {'ratio':>6s}")
    for text, reference in CASES:
        compile_ms = median_ms(lambda text=text: compile_expression(text), repeat=21)
        expr = compile_expression(text)
        np.testing.assert_allclose(expr(x, y, z), reference(x, y, z), rtol=1e-12, atol=1e-12)
        eval_ms = median_ms(lambda expr=expr: expr(x, y, z))
        numpy_ms = median_ms(lambda reference=reference: reference(x, y, z))
        print(f"{text[:55]:55s} {compile_ms:10.2f} {eval_ms:9.1f} {numpy_ms:9.1f} {eval_ms / numpy_ms:6.2f}")


if __name__ == "__main__":
    main()
