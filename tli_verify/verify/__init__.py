"""Bisimulation campaigns (paper Sec. 4.4, Thm. 2, Asm. 2): hypothesis perturbation sequences
against invariance and reachability, an oracle independent of the policy code, shrunk and
replayable counterexamples.

* :mod:`.strategies` -- public, composable hypothesis strategies for perturbation sequences;
* :mod:`.oracle` -- the four checks on a closed-loop trace, a :class:`~.oracle.Verdict` per run;
* :mod:`.campaign` -- :class:`~.campaign.CampaignConfig`, :func:`~.campaign.run_campaign`;
* :mod:`.backends` -- where the batches run (serial, local processes, Dask).

Nothing here is imported by ``import tli_verify``; hypothesis is imported by the modules that
need it.
"""
