"""Every resource and range limit on inputs, in one place.

A hostile or broken input must never crash the tool, exhaust memory, stall it, or get
certified: it is refused as bad input (exit 2) with one line that names the limit, the file and
the place (``docs/reference/limits.md``). These are the
limits the readers enforce; the certificate records the numeric ones
(:func:`tli_verify.model.types.numeric_limits`).

Size and shape of input files (:mod:`tli_verify.io`)
    ``MAX_INPUT_BYTES``, ``MAX_NESTING``; only regular files are read (no devices, FIFOs or
    sockets: ``/dev/zero`` or a pipe would never end).
Demonstrations (:mod:`tli_verify.demos`)
    ``MAX_STATE_DIM``, ``MAX_ABS_VALUE`` for states and velocities.
Models (:mod:`tli_verify.model`)
    ``MAX_ABS_VALUE`` for every number but the covariances; ``MAX_ABS_COVARIANCE``,
    ``COV_MIN_EIGENVALUE`` and ``COV_MAX_CONDITION`` for the GMM covariances; ``PRIOR_SUM_TOL``
    for the mixing weights.
GR(1) formulas (:mod:`tli_verify.logic.ltl`)
    ``MAX_FORMULA_NODES`` and ``MAX_FORMULA_DEPTH``: what a formula costs, not how long its
    text is (a file is at most ``MAX_INPUT_BYTES``).
Campaigns and counterexample cases (:mod:`tli_verify.verify`)
    ``MAX_CAMPAIGN_STEPS`` for the perturbation window, a case's steps and the sensor lag;
    ``MAX_PUSHES`` perturbations per case.
"""

from __future__ import annotations

__all__ = [
    "COV_MAX_CONDITION",
    "COV_MIN_EIGENVALUE",
    "MAX_ABS_COVARIANCE",
    "MAX_ABS_VALUE",
    "MAX_BATCH_SIZE",
    "MAX_CAMPAIGN_STEPS",
    "MAX_DEMO_SAMPLES",
    "MAX_EXAMPLES",
    "MAX_FORMULA_DEPTH",
    "MAX_FORMULA_NODES",
    "MAX_IMPORT_CELLS",
    "MAX_INPUT_BYTES",
    "MAX_NAME_BYTES",
    "MAX_NESTING",
    "MAX_PUSHES",
    "MAX_SEED",
    "MAX_STATE_DIM",
    "MAX_WORKERS",
    "PRIOR_SUM_TOL",
]

MAX_INPUT_BYTES = 4 * 1024 * 1024
"""Largest input file (spec, demonstration, model, certificate) read, in bytes (4 MiB).

The bundled model is 20 kB and a LASA model about 30 kB; 4 MiB is two orders of magnitude
above any model, spec or demonstration the tool produces or the paper uses."""

MAX_NAME_BYTES = 255
"""Longest component of a path (a file or folder name) read or written, in bytes of its
file-system encoding: the limit (NAME_MAX) of every common Linux and macOS file system. A longer
name is refused as bad input before any work, never left to fail as ``ENAMETOOLONG`` inside."""

MAX_NESTING = 64
"""Deepest nesting of ``[``/``{`` brackets (outside strings) in an input file.

Models and certificates nest 7 levels deep, specs 3; Python's JSON and TOML parsers recurse
once per level and die near 1000, so anything deeper than 64 is refused before parsing."""

MAX_FORMULA_NODES = 500_000
"""Most operator nodes of one parsed GR(1) formula (sub-formulas that Spot shares are counted
at every use, so ``F[1:3]``-style expansions count in full).

Every pass over a formula (classification, BDD construction) is linear in its nodes; at
500,000 the BDD construction takes a few seconds. The field's largest real specs (a
Spectra benchmark formula of 251,486 characters) have far fewer nodes than characters."""

MAX_FORMULA_DEPTH = 100
"""Deepest nesting accepted in a GR(1) formula: of parentheses in the text, of prefix
operators before Spot parses it (Spot itself crashes on some 10^5-deep ``X X ... a``), and of
operators in the parsed formula (``a -> a -> ...`` nests without parentheses). Real task and
benchmark formulas nest a few levels (n-ary ``&``/``|`` are one level); the limit keeps every
recursive pass over a formula far from Python's recursion limit."""

MAX_IMPORT_CELLS = 4096
"""Most variables one Spectra array declares (the product of its dimensions, each at most
4096), and most copies of a body nested ``forall``/``exists`` expand (the product of their
domains) in ``tli spec import``: checked before any is made. Each is a Boolean variable or a
copy of a formula in the translated spec, which GR(1) synthesis handles in the hundreds."""

MAX_STATE_DIM = 32
"""Largest state dimension ``n`` of a demonstration (and so of a learned model).

Learning solves SDPs with an ``n x n`` matrix variable and K PSD constraints of size n: at
n = 32 with 200 samples it takes about 13 s and 460 MB; at n = 200 the solver exhausts memory
and aborts the process. Robot states in the paper are 2D (scooping, LASA) to 7D (joints)."""

MAX_ABS_VALUE = 1.0e6
"""Largest magnitude of a demonstrated state or velocity, and of every number in a model
except the covariances (attractor, P, means, A_k, cut normals and points).

States in the units the paper uses (metres, millimetres: LASA spans about 50 mm) are 3-6 orders
of magnitude inside it. With it, ``|A_k (x - x*)| <= n * 1e6 * 2e6`` at every state with
``|x_i| <= 1e6`` (``docs/design.md``, "Errors and limits")."""

MAX_DEMO_SAMPLES = 100_000
"""Most samples (rows) of one demonstration: what ``tli learn`` reads and what ``tli demos``
writes (every script's ``duration / dt``, checked when the task loads, together with the
bound that its CSV fits ``MAX_INPUT_BYTES``). The paper's demonstrations have hundreds of
samples; learning fits a GMM on every one."""

MAX_ABS_COVARIANCE = MAX_ABS_VALUE**2
"""Largest magnitude of a GMM covariance entry (1e12): covariances have squared state units."""

COV_MIN_EIGENVALUE = 1.0e-100
"""Smallest eigenvalue allowed for a GMM covariance.

It keeps the mixing weights finite at every state with ``|x_i| <= MAX_ABS_VALUE``: each
Mahalanobis term is at most ``n * (2e6)^2 / 1e-100 <= 32 * 4e112``, and the terms of the
quadratic form at most ``1e100 * 4e12`` each, far below the double overflow at 1.8e308; the
weights are then non-negative and sum to 1, which is all the Lyapunov certificate needs (it holds
for every convex combination of the ``A_k``). A covariance near 1e-320 (subnormal) has an
overflowing inverse and is refused. Learned covariances are at least 1e-3 times the data
variance."""

COV_MAX_CONDITION = 1.0e12
"""Largest condition number ``lambda_max / lambda_min`` of a GMM covariance.

Inverting a matrix loses about ``log10(cond)`` of the 16 significant digits of a double; at
1e12 four digits remain, enough for mixing weights. Learned covariances have cond < 1e4."""

PRIOR_SUM_TOL = 1.0e-6
"""The GMM priors (all > 0) must sum to 1 within this tolerance."""

MAX_CAMPAIGN_STEPS = 100_000
"""Largest perturbation window, perturbation step and sensor lag of a campaign or a case, in
control steps (1,000 s at the scoop task's 10 ms): the run's step budget follows from them."""

MAX_PUSHES = 100
"""Most perturbations in one case (paper Asm. 2: finitely many)."""

MAX_EXAMPLES = 10_000_000
"""Most cases of one campaign (``tli verify --examples``; the evidence schema's bound)."""

MAX_BATCH_SIZE = 10_000
"""Most runs in one batch of a campaign (each chunk of draws is ``batch_size + 10`` cases)."""

MAX_WORKERS = 256
"""Most worker processes of a campaign or a study (``--workers`` of ``tli verify``, ``tli
evidence``, ``tli sim franka`` and ``tli experiment``; an evidence's ``campaign.workers``)."""

MAX_SEED = 2**32 - 1
"""Largest seed of a campaign, an episode or a study (numpy and hypothesis take 32 bits)."""
