"""numpy's BLAS runs on one thread while a frame renders, and as before afterwards."""

from __future__ import annotations

from threadpoolctl import threadpool_info

from addon.core.blas_threads import single_threaded_blas
from addon.core.frame import stages
from tests.core.test_progressive import BASE, closed_sphere


def blas_threads() -> list[int]:
    return [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]


def test_blas_runs_on_one_thread_inside_and_as_before_outside() -> None:
    before = blas_threads()
    assert before  # numpy's OpenBLAS is loaded
    with single_threaded_blas():
        assert blas_threads() == [1] * len(before)
    assert blas_threads() == before


def test_a_frame_renders_with_one_blas_thread(renderer, monkeypatch) -> None:
    seen = []
    run = stages.CheckInput.run

    def recording(self, frame) -> None:
        seen.append(blas_threads())
        run(self, frame)

    monkeypatch.setattr(stages.CheckInput, "run", recording)
    renderer.render(closed_sphere(), BASE)
    assert seen and all(n == 1 for n in seen[0])
