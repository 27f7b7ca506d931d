"""A fork-based process pool works after ``RLSBank(parallel=True)`` ran (#27 item 6).

With numba's default threading layer on a machine with GNU OpenMP, a forked
worker aborted ("fork() called from a process already using GNU OpenMP") and
the pool never returned; rlsfilt selects numba's "forksafe" layers.
"""

import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent("""
    import multiprocessing as mp
    import numpy as np
    from rlsfilt import RLSBank

    def work(seed):
        bank = RLSBank(n_channels=64, dim_x=3, parallel=True)
        H = np.random.default_rng(seed).standard_normal((50, 64, 3))
        bank.batch_filter(H.sum(-1), H)
        return float(bank.x.sum())

    if __name__ == "__main__":
        first = work(0)
        with mp.get_context("fork").Pool(2) as pool:
            results = pool.map(work, range(3))
        assert results[0] == first, (results, first)
        import numba
        print(numba.threading_layer())
""")


def test_fork_pool_finishes_after_a_parallel_bank(tmp_path):
    script = tmp_path / "fork_pool.py"
    script.write_text(SCRIPT)
    env = {k: v for k, v in __import__("os").environ.items() if k != "NUMBA_THREADING_LAYER"}
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         timeout=600, env=env, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() in {"tbb", "workqueue", "omp"}
    assert "GNU OpenMP" not in out.stderr
