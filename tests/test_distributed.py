"""sweep across processes: two JAX processes on localhost (CPU collectives) against one process."""

import os
import socket
import subprocess
import sys
import textwrap

import numpy as np

WORKER = textwrap.dedent(
    """
    import sys
    import jax
    import numpy as np

    port, process_id, processes, path = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
    jax.config.update("jax_enable_x64", True)
    if processes > 1:
        jax.distributed.initialize(
            coordinator_address=f"127.0.0.1:{port}",
            num_processes=processes,
            process_id=process_id,
            initialization_timeout=120,
        )
    import tripodjax as tj
    from tripodjax.bench import random_layouts

    assert jax.process_count() == processes and len(jax.devices()) == 2 * processes
    layouts = tj.Layout(*random_layouts(64, seed=11))
    names = ("delta_pp", "irregularity", "gamma_pp", "ecc_max", "gaf_rms", "result")
    # 12 layouts per chunk: six chunks, the last one padded, each split over every device.
    newton = tj.sweep(layouts, n_theta=60, outputs=names, chunk_size=12, gaf=tj.GAFInputs(500.0))
    analytic = tj.sweep(layouts, n_theta=60, solver="analytic", chunk_size=12)
    # Each process holds (and evaluates) only its own devices' rows of a chunk.
    shards = []
    def double(part):
        shards.append((len(part.addressable_shards), part.is_fully_addressable))
        return jax.jit(lambda x: 2 * x)(part)
    doubled = tj.map_chunks(double, np.arange(10.0), 4)
    assert np.array_equal(doubled, 2 * np.arange(10.0))
    assert shards == [(2, processes == 1)] * 3, shards
    arrays = {f"newton_{k}": v for k, v in newton.items()}
    arrays.update({f"analytic_{k}": v for k, v in analytic.items()})
    np.savez(path, **arrays)
    """
)


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(tmp_path, port, process_id, processes):
    env = dict(
        os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=2", JAX_PLATFORMS="cpu"
    )
    path = tmp_path / f"out_{processes}_{process_id}.npz"
    args = [sys.executable, "-c", WORKER, str(port), str(process_id), str(processes), str(path)]
    process = subprocess.Popen(
        args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    return process, path


def _finish(process):
    try:
        _, err = process.communicate(timeout=600)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0, err[-4000:]


def test_sweep_on_two_processes_equals_one_process(tmp_path):
    """Each of two processes (two CPU devices each) evaluates its share; both get the whole answer."""
    port = _free_port()
    workers = [_start(tmp_path, port, i, 2) for i in range(2)]
    single, single_path = _start(tmp_path, 0, 0, 1)
    for process, _ in [*workers, (single, single_path)]:
        _finish(process)
    reference = np.load(single_path)
    assert set(reference.files) >= {"newton_gaf_rms", "analytic_converged"}
    assert np.all(reference["newton_result"] == 0)
    for _, path in workers:
        out = np.load(path)
        assert sorted(out.files) == sorted(reference.files)
        for name in reference.files:
            np.testing.assert_array_equal(out[name], reference[name], err_msg=name)
