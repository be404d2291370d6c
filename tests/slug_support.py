"""Test helper of the slug model: a run killed (as by kill -9) right after a checkpoint."""

import pytest

from eulag import slug


def killed_after_checkpoint(case, out, monkeypatch, n=1):
    """Run ``case`` to ``out`` and stop it right after its ``n``-th checkpoint was written, as
    kill -9 would; return the checkpoint's path."""
    real = slug.savez_atomic
    calls = []

    def write_then_stop(path, state):
        real(path, state)
        calls.append(path)
        if len(calls) == n:
            raise KeyboardInterrupt  # stands for kill -9 right after the checkpoint was written

    monkeypatch.setattr(slug, "savez_atomic", write_then_stop)
    with pytest.raises(KeyboardInterrupt):
        slug.run_slug(case, out, progress=False)
    monkeypatch.setattr(slug, "savez_atomic", real)
    return slug.checkpoint_path(out)
