"""The least of interleaved rounds, shared by the benchmark scripts."""


def least(reps, scenes, variants, run):
    """Runs `run(scene, variant)` for every scene and variant, `reps`
    rounds interleaved (so that a slow spell of the machine falls on all of
    them alike), and keeps per (scene, variant) the result with the least
    `total` seconds; runs that return None (failed) are left out."""
    best = {}
    for _ in range(reps):
        for scene in scenes:
            for variant in variants:
                r = run(scene, variant)
                if r is None:
                    continue
                key = (scene, variant)
                if key not in best or r["total"] < best[key]["total"]:
                    best[key] = r
    return best
