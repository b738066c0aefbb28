"""A sweep's local Ray head (analysis/ray_head.py): a head that cannot start Ray is an error naming it, and
waiting for it neither hangs nor leaves the head behind."""

from __future__ import annotations

import pytest

from econmotor.analysis.ray_head import local_ray_head
from econmotor.errors import BackendError


def test_a_head_that_cannot_start_ray_is_an_error_not_a_hang():
    pytest.importorskip("ray", reason="Ray is the optional extra `econmotor[ray]`")
    with pytest.raises(BackendError, match="Ray's local head ended before Ray started"):
        with local_ray_head({"no_such_ray_init_argument": 1}):
            pass
