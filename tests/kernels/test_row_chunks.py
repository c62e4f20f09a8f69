"""Work on the flagged rows of a batch alone (``sgjax.kernels.row_chunks``)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sgjax.kernels.row_chunks import chunk_size, update_flagged_rows


def test_chunk_size_is_a_sixteenth_within_its_bounds():
    assert [chunk_size(n) for n in (1, 5, 8, 40, 256, 1000)] == [1, 5, 8, 8, 16, 63]
    assert chunk_size(40, minimum=3) == 3


@pytest.mark.parametrize("chunk", [1, 3, 8])
def test_every_flagged_row_is_updated_once_in_order_and_no_other(chunk):
    """Each flagged row is visited exactly once, chunk by chunk in row order; the padding
    places hold N; nothing is flagged: no update runs."""
    flags = jax.random.uniform(jax.random.key(0), (20,)) < 0.4

    def update(index, carry):
        visits, order, seen = carry
        visits = visits.at[index].add(1, mode="drop")
        order = order.at[index].set(seen + jnp.arange(chunk), mode="drop")
        return visits, order, seen + jnp.where(jnp.all(index <= 20), chunk, -1000)  # pad: N

    init = (jnp.zeros(20, jnp.int32), jnp.full(20, -1), jnp.int32(0))
    visits, order, seen = jax.jit(update_flagged_rows, static_argnums=(1, 2))(
        flags, chunk, update, init)
    flagged = np.asarray(flags)
    np.testing.assert_array_equal(np.asarray(visits), flagged.astype(int))
    assert int(seen) == chunk * -(-flagged.sum() // chunk)  # ceil(flagged / chunk) chunks
    assert np.all(np.diff(np.asarray(order)[flagged]) > 0)  # in row order
    untouched = update_flagged_rows(jnp.zeros(20, bool), chunk, update, init)
    assert int(untouched[2]) == 0
