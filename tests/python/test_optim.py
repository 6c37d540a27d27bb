"""Adam against Algorithm 1 of Kingma and Ba written here and against torch.optim.Adam;
L-BFGS on the Rosenbrock function; errors and Python exceptions through the C++ loop."""
import numpy as np
import pytest

import wavebrdf as wb


def test_adam_follows_algorithm_1(rng):
    lr, b1, b2, eps, decay = 0.05, 0.8, 0.95, 1e-6, 0.1
    adam = wb.Adam(6, lr=lr, beta1=b1, beta2=b2, epsilon=eps, decay=decay)
    x = rng.normal(size=(2, 3))
    ref = x.copy()
    m = np.zeros_like(x)
    v = np.zeros_like(x)
    for t in range(1, 8):
        epoch = t // 2  # several steps may share an epoch
        g = np.sin(3 * ref) + ref
        out = adam.step(x, np.sin(3 * x) + x, epoch)
        assert out is not None and np.shares_memory(out, x)  # updated in place
        m = b1 * m + (1 - b1) * g
        v = b2 * v + (1 - b2) * g ** 2
        step = lr * np.exp(-decay * epoch)
        ref = ref - step * (m / (1 - b1 ** t)) / (np.sqrt(v / (1 - b2 ** t)) + eps)
        np.testing.assert_allclose(x, ref, rtol=1e-12, atol=1e-14)
    assert adam.steps == 7 and adam.size == 6
    np.testing.assert_allclose(adam.m, m.ravel(), rtol=1e-12)
    np.testing.assert_allclose(adam.v, v.ravel(), rtol=1e-12)
    assert adam.learning_rate(3) == pytest.approx(lr * np.exp(-0.3))


def test_adam_matches_torch():
    torch = pytest.importorskip("torch")
    x0 = np.linspace(-1, 1, 10)
    p = torch.tensor(x0, requires_grad=True)
    opt = torch.optim.Adam([p], lr=0.01, betas=(0.9, 0.99), eps=1e-8)
    adam = wb.Adam(10, decay=0.0)
    x = x0.copy()
    for _ in range(20):
        opt.zero_grad()
        (p ** 4 - p).sum().backward()
        opt.step()
        adam.step(x, 4 * x ** 3 - 1)
    np.testing.assert_allclose(x, p.detach().numpy(), rtol=1e-10, atol=1e-12)


def test_adam_state_round_trip(rng):
    a = wb.Adam(4)
    x = rng.normal(size=4)
    for e in range(3):
        a.step(x, x, e)
    b = wb.Adam(4)
    b.set_state(a.m, a.v, a.steps)
    xa, xb = x.copy(), x.copy()
    a.step(xa, xa, 3)
    b.step(xb, xb, 3)
    np.testing.assert_array_equal(xa, xb)


@pytest.mark.parametrize("call,message", [
    (lambda a: a.step(np.zeros(3, dtype=np.float32), np.zeros(3)), "x has dtype float32"),
    (lambda a: a.step([0.0, 0.0, 0.0], np.zeros(3)), "x is not a NumPy array"),
    (lambda a: a.step(np.zeros(4), np.zeros(4)), "x has 4 values"),
    (lambda a: a.step(np.zeros((3, 2))[:, 0], np.zeros(3)), "C-contiguous"),
    (lambda a: a.step(np.zeros(3), np.zeros(2)), "gradient has 2 values"),
    (lambda a: a.step(np.zeros(3), np.array([0.0, np.nan, 0.0])), "gradient[1]"),
    (lambda a: a.step(np.zeros(3), np.zeros(3), -1), "epoch"),
])
def test_adam_errors(call, message):
    with pytest.raises(ValueError) as e:
        call(wb.Adam(3))
    assert message in str(e.value)


@pytest.mark.parametrize("kwargs", [dict(lr=0), dict(beta1=1.0), dict(beta2=-0.1), dict(epsilon=0), dict(decay=-1),
                                    dict(lr=float("nan"))])
def test_adam_option_errors(kwargs):
    with pytest.raises(ValueError):
        wb.Adam(3, **kwargs)


def rosenbrock(x):
    a, b = x[..., 0], x[..., 1]
    value = (1 - a) ** 2 + 100 * (b - a * a) ** 2
    grad = np.stack([-2 * (1 - a) - 400 * a * (b - a * a), 200 * (b - a * a)], axis=-1)
    return float(value), grad


def test_lbfgs_minimises_rosenbrock():
    calls = []

    def f(x):
        calls.append(x.copy())
        return rosenbrock(x)

    x, result = wb.lbfgs_minimize(f, np.array([[-1.2, 1.0]]), max_iterations=200, gradient_tolerance=1e-8)
    assert x.shape == (1, 2)
    np.testing.assert_allclose(x, [[1.0, 1.0]], atol=1e-6)
    assert result.converged and result.value < 1e-12
    assert result.evaluations == len(calls) and result.iterations <= 200
    assert all(c.shape == (1, 2) for c in calls)


def test_lbfgs_callback_and_exceptions():
    seen = []
    x, result = wb.lbfgs_minimize(rosenbrock, np.array([-1.2, 1.0]),
                                  callback=lambda i, v: seen.append((i, v)) or i < 3)
    assert result.iterations == 3 and [i for i, _ in seen] == [1, 2, 3]  # stopped by returning False
    assert seen[-1][1] == pytest.approx(result.value)

    class Boom(Exception):
        pass

    def raises(x):
        raise Boom("from the objective")

    with pytest.raises(Boom):
        wb.lbfgs_minimize(raises, np.zeros(2))
    with pytest.raises(ValueError, match="expected a pair"):
        wb.lbfgs_minimize(lambda x: 1.0, np.zeros(2))
    with pytest.raises(ValueError, match="gradient has 3 values"):
        wb.lbfgs_minimize(lambda x: (1.0, np.zeros(3)), np.zeros(2))
    with pytest.raises(ValueError):  # not finite at the start
        wb.lbfgs_minimize(lambda x: (float("nan"), np.zeros(2)), np.zeros(2))
    with pytest.raises(ValueError, match="history"):
        wb.lbfgs_minimize(rosenbrock, np.zeros(2), history=0)
    with pytest.raises(ValueError, match="x0 is empty"):
        wb.lbfgs_minimize(rosenbrock, np.zeros(0))
