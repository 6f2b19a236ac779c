"""The service attacked — what the black-box attack found across several parts at once.

The render-target pool is the renderer's (renderer/gl/targets.py), bounded by the service's
POCKETRAY_MAX_TARGET_BYTES on its GL thread. The other defects of that attack are reproduced in
the files of the modules they were in: strict JSON and large bodies in api/test_body.py, the 422
list in api/test_errors.py, wire timeouts in http/test_wire.py, store faults in
sessions/test_store.py, ``Allow`` in http/test_allow.py, refused gestures and settings in
api/routes/.

No timing decides a test here except generous hang guards (the figures are bench/hostile.py's).
"""

from __future__ import annotations


def test_the_render_target_pool_is_bounded_in_bytes_not_entries(ready_client):
    """Rules out: up to 9 sizes with two RGBA32F targets each (frames at 11 sizes near 4096² left 5.3 GB).
    The 11-size sequence at small sizes on the GL thread: free targets never exceed the bound, busy
    ones are never taken away, and the service's pool has POCKETRAY_MAX_TARGET_BYTES as its bound."""
    from renderer.gl.targets import TargetPool

    worker, config = ready_client.app.state.worker, ready_client.app.state.config
    sizes = [(64 + 8 * i, 48 + 8 * i) for i in range(11)]
    bound = 3 * TargetPool.nbytes_of(*sizes[-1])

    def job(renderer):
        assert renderer.targets.max_bytes == config.max_target_bytes
        pool = TargetPool(renderer.ctx, bound)
        seen = []
        held = pool.acquire(*sizes[0])  # busy all along: never released by the pool
        for w, h in sizes:
            fbo = pool.acquire(w, h)
            pool.release(fbo)
            seen.append((pool.nbytes - pool.nbytes_of(*sizes[0]), len(pool.sizes)))
        again = pool.acquire(*sizes[-1])  # the most recent free size is reused
        reused = again.glo == fbo.glo
        pool.release(again)
        pool.release(held)
        total = pool.nbytes
        pool.clear()
        return seen, reused, total

    with worker.admit() as ticket:
        seen, reused, total = ticket.run(job, 30)
    assert all(free <= bound for free, _ in seen), seen
    # At the end the three largest (most recent) free sizes fill the bound, plus the busy one; on
    # the way the smaller sizes were kept as long as they fitted (up to 8 entries: bytes, not a count).
    assert seen[-1][1] == 4 and max(n for _, n in seen) > 4 and reused
    assert total <= bound + TargetPool.nbytes_of(*sizes[0])
