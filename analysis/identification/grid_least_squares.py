"""Non-negative least squares for many candidate column sets at once: a grid search's inner fit.

``settled_curve`` profiles each valve's starting current, saturation current and play over a grid
of some hundred thousand points, and at each fits the curves' weights by non-negative least
squares: a free offset, the other valves' columns (held) and the candidate's own few columns,
every weight but the offset's at least zero. One ``scipy.optimize.nnls`` call per point and sign
takes 4.5 s for one valve's grid, this 0.49 s (``benchmarks/grid_least_squares.py``, 30 levels,
21 plays): so many small problems that share most of their columns are solved here together,
exactly.

Why it is exact: the non-negative optimum is the unconstrained least-squares fit on its own
support (the columns whose weights are positive). So the lowest sum of squares over every subset
of the columns whose unconstrained fit has no negative weight is the optimum: each such fit is a
feasible point, and the optimum's support is among the subsets. A subset whose columns are
linearly dependent is skipped, which loses nothing: a fit on dependent columns is also a fit with
non-negative weights on fewer, independent ones (Caratheodory's theorem for cones). With few
columns (two held, two per candidate: 15 subsets) the subsets are solved in closed form, batched
over the candidates: the held subset is projected out first (a Schur complement), so each
candidate costs a few products of 2 x 2 matrices.
"""

import itertools

import numpy as np

# A subset's Gram matrix is taken as singular below this share of its diagonal's product
# (Hadamard's bound: a Gram matrix's determinant never exceeds it), and a column as empty
# when the held columns or the offset leave less than this share of its squared norm.
_SINGULAR = 1e-10


def lowest_sums_of_squares(y, held, candidates, weights=None) -> np.ndarray:
    """(K, 2) the non-negative least-squares fit's weighted sum of squares per candidate and sign.

    The fit is of ``y`` by a free offset, the ``held`` columns and one candidate's columns, each
    coefficient but the offset's at least zero; in column 0 with the candidate's columns as
    given, in column 1 with them negated (a valve whose opening lowers the output).

    Args:
        y: (M,) the values fitted.
        held: (M, H) the columns every candidate shares (H may be 0).
        candidates: (K, M, C) each candidate's own columns.
        weights: (M,) each value's weight in the sum of squares, all positive (default all 1).
    """
    y, held, candidates = (np.asarray(a, float) for a in (y, held, candidates))
    if held.ndim != 2 or held.shape[0] != y.size:
        raise ValueError(f"held: expected shape ({y.size}, H), got {held.shape}")
    if candidates.ndim != 3 or candidates.shape[1] != y.size:
        raise ValueError(f"candidates: expected shape (K, {y.size}, C), got {candidates.shape}")
    root = np.ones(y.size) if weights is None else np.sqrt(np.asarray(weights, float))
    if root.shape != y.shape or not np.all(root > 0.0):
        raise ValueError(f"weights: expected {y.size} positive values, got {weights!r}")
    # Weighted, every row is scaled by its weight's root, the offset's column too; the free
    # offset is then projected out along that column.
    y, held, candidates = y * root, held * root[:, None], candidates * root[:, None]
    raw_norms = np.sum(candidates * candidates, axis=1)
    offset = root / np.linalg.norm(root)
    y = y - offset * (offset @ y)
    held = held - np.outer(offset, offset @ held)
    candidates = candidates - offset[:, None] * (offset @ candidates)[:, None, :]
    hh, hy, yy = held.T @ held, held.T @ y, float(y @ y)
    transposed = candidates.transpose(0, 2, 1)
    bb = transposed @ candidates
    by = transposed @ y
    bh = transposed @ held
    own_norms = np.diagonal(bb, axis1=1, axis2=2)  # (K, C): what the offset left of each column
    # An empty or constant column (a curve that is flat over every level) fits nothing.
    usable = own_norms > _SINGULAR * raw_norms
    lowest = np.full((candidates.shape[0], 2), yy)
    for held_set in _subsets(held.shape[1], include_empty=True):
        gram = hh[np.ix_(held_set, held_set)]
        inverse = np.zeros((0, 0))
        if held_set.size:
            if not _nonsingular(gram[None])[0]:
                continue
            inverse = np.linalg.inv(gram)
        held_alone = inverse @ hy[held_set]
        cross = bh[:, :, held_set]  # (K, C, |held_set|)
        if np.all(held_alone >= 0.0):
            lowest = np.minimum(lowest, yy - hy[held_set] @ held_alone)
        # The candidate's columns with the held subset projected out (a Schur complement), and
        # how each of its weights moves the held subset's.
        reduced_bb = bb - cross @ inverse @ cross.transpose(0, 2, 1)
        reduced_by = by - cross @ held_alone
        reduced_yy = yy - hy[held_set] @ held_alone
        pull = cross @ inverse  # (K, C, |held_set|)
        for own_set in _subsets(candidates.shape[2], include_empty=False):
            gram_own = reduced_bb[:, own_set][:, :, own_set]
            # The determinant test is relative, so a column the held ones span must also be
            # caught by what the projection left of it.
            left = np.diagonal(gram_own, axis1=1, axis2=2)
            solvable = _nonsingular(gram_own) & np.all(usable[:, own_set], axis=1)
            solvable &= np.all(left > _SINGULAR * own_norms[:, own_set], axis=1)
            # Negating the candidate's columns negates its weights and leaves the held weights
            # and the sum of squares as they are: one solve serves both signs.
            own = _solve(
                np.where(solvable[:, None, None], gram_own, np.eye(own_set.size)),
                reduced_by[:, own_set],
            )
            sse = reduced_yy - np.einsum("ki,ki->k", reduced_by[:, own_set], own)
            held_weights = held_alone - np.einsum("ki,kij->kj", own, pull[:, own_set])
            solvable &= np.all(held_weights >= 0.0, axis=1)
            for column, sign in enumerate((1.0, -1.0)):
                feasible = solvable & np.all(sign * own >= 0.0, axis=1)
                lowest[:, column] = np.where(
                    feasible, np.minimum(lowest[:, column], sse), lowest[:, column]
                )
    # Rounding can leave a perfect fit a hair below zero.
    return np.maximum(lowest, 0.0)


def _subsets(count: int, include_empty: bool) -> list[np.ndarray]:
    """Every subset of range(count), as index arrays, smallest first."""
    sizes = range(0 if include_empty else 1, count + 1)
    return [np.array(s, dtype=int) for n in sizes for s in itertools.combinations(range(count), n)]


def _nonsingular(grams: np.ndarray) -> np.ndarray:
    """(K,) whether each (K, n, n) Gram matrix is far enough from singular to solve."""
    diagonal_product = np.prod(np.diagonal(grams, axis1=1, axis2=2), axis=1)
    return (diagonal_product > 0.0) & (_determinant(grams) > _SINGULAR * diagonal_product)


def _determinant(grams: np.ndarray) -> np.ndarray:
    """(K,) each (K, n, n) matrix's determinant.

    Written out for n <= 2, where LAPACK's batched call costs more per matrix than the arithmetic.
    """
    if grams.shape[1] == 1:
        return grams[:, 0, 0]
    if grams.shape[1] == 2:
        return grams[:, 0, 0] * grams[:, 1, 1] - grams[:, 0, 1] * grams[:, 1, 0]
    return np.linalg.det(grams)


def _solve(grams: np.ndarray, rights: np.ndarray) -> np.ndarray:
    """(K, n) the solutions of (K, n, n) nonsingular systems; Cramer's rule for n <= 2."""
    if grams.shape[1] == 1:
        return rights / grams[:, 0]
    if grams.shape[1] == 2:
        determinant = _determinant(grams)[:, None]
        return (
            np.column_stack(
                [
                    grams[:, 1, 1] * rights[:, 0] - grams[:, 0, 1] * rights[:, 1],
                    grams[:, 0, 0] * rights[:, 1] - grams[:, 1, 0] * rights[:, 0],
                ]
            )
            / determinant
        )
    return np.linalg.solve(grams, rights[:, :, None])[:, :, 0]
