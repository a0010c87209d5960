"""Learning a :class:`~rollability_ros.core.campaign.likelihood.LearntLikelihood` from simulated launches
(:func:`~rollability_ros.core.campaign.likelihood.simulate_training_set`): the ensemble's perceptrons, fitted
with scikit-learn (imported only here, by :func:`fit_network`) in a pool's worker processes when given, their
weights copied into plain arrays; the classifier's held-out accuracy against a constant and its reliability
table. docs/calibration.md, "The learnt likelihood"."""
import concurrent.futures
import contextlib
import typing

import numpy as np

from rollability_ros.core.campaign.adaptive import Unknowns
from rollability_ros.core.campaign.likelihood import (HIDDEN, MEMBERS, OUTCOMES, PROBABILITY_FLOOR, ConditionLevels,
                                                      Layers, LearntLikelihood, Member, TrainingSet, transform)
from rollability_ros.core.optional import require

Task = typing.Tuple[str, np.ndarray, np.ndarray, int, typing.Optional[np.ndarray]]


def _layers_of(model: typing.Any) -> Layers:
    return [(np.asarray(w, dtype=np.float64), np.asarray(b, dtype=np.float64))
            for w, b in zip(model.coefs_, model.intercepts_)]


#: The perceptrons' training options (scikit-learn's names; ``random_state`` is each fit's own).
TRAINING = {"hidden_layer_sizes": HIDDEN, "activation": "relu", "alpha": 1e-4, "max_iter": 300,
            "early_stopping": True, "n_iter_no_change": 15}


def fit_network(kind: str, x: np.ndarray, y: np.ndarray, seed: int,
                predict: typing.Optional[np.ndarray] = None) -> typing.Tuple[Layers, typing.Optional[np.ndarray]]:
    """One perceptron fitted (``kind`` ``classifier``: a logit output; ``regressor``) on ``x`` (n, f), ``y`` (n,)
    with :data:`TRAINING`'s options and ``seed``; its layers, and its predictions (probabilities of the positive
    class for a classifier) at ``predict`` (m, f) when given. A function of plain arrays, so a worker process can
    run it."""
    neural = require("sklearn.neural_network", feature="preparing a learnt likelihood")
    try:   # a worker's BLAS threads only contend with the other workers
        limits: typing.Any = require("threadpoolctl").threadpool_limits(1)
    except ImportError:
        limits = contextlib.nullcontext()
    with limits:
        if kind == "classifier":
            model = neural.MLPClassifier(**TRAINING, random_state=seed).fit(x, y > 0.5)
            out = model.predict_proba(predict)[:, 1] if predict is not None else None
        else:
            model = neural.MLPRegressor(**TRAINING, random_state=seed).fit(x, y)
            out = model.predict(predict) if predict is not None else None
    return _layers_of(model), out


def _fit_all(tasks: typing.Sequence[Task], pool: typing.Optional[concurrent.futures.Executor]) -> typing.List[typing.Tuple[Layers, typing.Any]]:
    if pool is None:
        return [fit_network(*task) for task in tasks]
    return list(pool.map(fit_network, *zip(*tasks)))


def reliability(probabilities: np.ndarray, outcomes: np.ndarray, bins: int = 10) -> typing.List[typing.List[float]]:
    """A reliability table of ``probabilities`` and 0/1 ``outcomes`` (n,) each: per decile of the predicted
    probabilities ``[mean predicted, observed frequency, launches]`` (empty bins left out)."""
    edges = np.quantile(probabilities, np.linspace(0.0, 1.0, bins + 1))
    which = np.clip(np.searchsorted(edges, probabilities, side="right") - 1, 0, bins - 1)
    return [[float(probabilities[which == b].mean()), float(outcomes[which == b].mean()), int((which == b).sum())]
            for b in range(bins) if (which == b).any()]


def held_out_accuracy(predictions: typing.Sequence[np.ndarray], y: np.ndarray, base_rate: float,
                      say: typing.Callable[[str], None]) -> typing.Dict[str, object]:
    """The ensemble's verdict on held-out launches ``y`` (m,) from each member's P(upright) ``predictions``
    against a constant ``base_rate`` (the training launches' upright fraction): log losses, Brier scores, the
    members' spread and the reliability table (``info`` entries), said in one line."""
    p = np.clip(np.mean(predictions, axis=0), PROBABILITY_FLOOR, 1 - PROBABILITY_FLOOR)
    first = np.clip(predictions[0], PROBABILITY_FLOOR, 1 - PROBABILITY_FLOOR)
    base = float(np.clip(base_rate, PROBABILITY_FLOOR, 1 - PROBABILITY_FLOOR))

    def log_loss(q: typing.Union[np.ndarray, float]) -> float:
        """Mean log loss of predicted probabilities ``q`` (n,) (or one constant) against the held-out verdicts."""
        return float(-np.mean(y * np.log(q) + (~y) * np.log1p(-np.asarray(q))))
    scores = {"holdout_log_loss": log_loss(p), "holdout_log_loss_first_member": log_loss(first),
              "holdout_log_loss_constant": log_loss(base),
              "holdout_brier": float(np.mean((p - y) ** 2)),
              "holdout_brier_constant": float(np.mean((base - y) ** 2)),
              "holdout_member_spread": float(np.mean(np.std(predictions, axis=0)))}
    table = reliability(p, y.astype(np.float64))
    worst = max(abs(a - b) for a, b, _ in table)
    say(f"upright classifier ({len(predictions)} members), {len(y)} held-out launches: log loss "
        f"{scores['holdout_log_loss']:.3f} (one member {scores['holdout_log_loss_first_member']:.3f}, a constant "
        f"{scores['holdout_log_loss_constant']:.3f}), Brier {scores['holdout_brier']:.3f} (constant "
        f"{scores['holdout_brier_constant']:.3f}); reliability: deciles' predicted vs observed differ by at most "
        f"{worst:.3f}; members' spread {scores['holdout_member_spread']:.3f}")
    return {**scores, "holdout_reliability": table}


def learn(training: TrainingSet, unknowns: Unknowns, configurations: typing.Sequence[str], levels: ConditionLevels,
          fingerprint: str, seed: int = 1, holdout_fraction: float = 0.15,
          on_progress: typing.Optional[typing.Callable[[str], None]] = None, members: int = MEMBERS,
          pool: typing.Optional[concurrent.futures.Executor] = None) -> LearntLikelihood:
    """Learn the networks (module docstring) from ``training``'s valid launches: ``members`` classifiers and
    location networks (the first on the launches as drawn, each further one on a resample with replacement and
    its own seed), the scales from the first member's cross-fitted residuals. The last ``holdout_fraction`` of
    the launches is never trained on by the classifiers: it measures the ensemble's verdict (log loss and Brier
    score against a constant, a reliability table), recorded in ``info``. The fits run in ``pool``'s workers
    when given. scikit-learn is imported by :func:`fit_network`."""
    say = on_progress or (lambda line: None)
    if members < 1:
        raise ValueError(f"members must be >= 1, got {members}")
    valid = training.rows[:, 0] > 0.5
    n = int(valid.sum())
    if n < 50:
        raise ValueError(f"only {n} valid training launches: prepare with more launches")
    u = training.normalised[valid]
    onehot = np.eye(len(configurations))[training.configuration[valid]]
    condition = training.condition[valid]
    raw = np.concatenate([u, onehot, levels.features(condition[:, 0], condition[:, 1], condition[:, 2])], axis=1)
    mean, std = raw.mean(axis=0), raw.std(axis=0)
    std = np.where(std > 1e-9, std, 1.0)
    x = (raw - mean) / std
    rows = training.rows[valid]
    upright = rows[:, 1] > 0.5
    held = np.arange(n) >= int(round(n * (1.0 - holdout_fraction)))
    rng = np.random.default_rng(seed)
    trained = np.flatnonzero(~held)

    def resample(indices: np.ndarray, k: int) -> np.ndarray:
        """Member ``k``'s training rows: ``indices`` (n,) themselves for the first, a bootstrap draw (n,) after."""
        return indices if k == 0 else rng.choice(indices, size=len(indices), replace=True)
    tasks: typing.List[Task] = []
    for k in range(members):
        pick = resample(trained, k)
        tasks.append(("classifier", x[pick], upright[pick].astype(np.float64), seed + k, x[held]))
    xv = np.concatenate([x, np.where(upright, 1.0, -1.0)[:, None]], axis=1)
    measured: typing.List[typing.Tuple[str, np.ndarray, np.ndarray, np.ndarray]] = []
    for j, name in enumerate(OUTCOMES):
        target = transform(name, rows[:, 2 + j], condition[:, 1])
        finite = np.flatnonzero(np.isfinite(target))
        if len(finite) < 50:
            say(f"{name}: {len(finite)} launches measured it: not learnt")
            continue
        # the scale learns from cross-fitted residuals (each half predicted by a location net that never saw it),
        # so it carries the location's error at launches it was not trained on, not only the launches' scatter
        half = np.arange(len(finite)) % 2 == 0
        measured.append((name, finite, target, half))
        for fit_on in (half, ~half):
            tasks.append(("regressor", xv[finite[fit_on]], target[finite[fit_on]], seed, xv[finite[~fit_on]]))
        for k in range(members):
            pick = resample(finite, k)
            tasks.append(("regressor", xv[pick], target[pick], seed + k, None))
    say(f"learning {len(tasks)} networks from {n} valid launches ({members} ensemble members)")
    fitted = iter(_fit_all(tasks, pool))
    classifiers = [next(fitted) for _ in range(members)]
    info: typing.Dict[str, typing.Any] = {
        "training_launches": int(len(training.rows)), "valid_launches": n, "upright_fraction": float(upright.mean()),
        "holdout_launches": int(held.sum()), "members": members,
        "training_normalised_range": [float(u.min()), float(u.max())],
        **held_out_accuracy([out for _, out in classifiers], upright[held], float(upright[~held].mean()), say)}
    location: typing.List[typing.Dict[str, Layers]] = [{} for _ in range(members)]
    scale_tasks = []
    for name, finite, target, half in measured:
        residual = np.empty(len(finite))
        for fit_on in (half, ~half):
            residual[~fit_on] = target[finite[~fit_on]] - next(fitted)[1]
        for k in range(members):
            location[k][name] = next(fitted)[0]
        scale_tasks.append(("regressor", xv[finite], np.log(residual ** 2 + 1e-12), seed, None))
        info[f"{name}_launches"] = int(len(finite))
        info[f"{name}_residual_sd"] = float(np.std(residual))
        say(f"{name}: learnt from {len(finite)} launches, cross-fitted residual sd {np.std(residual):.3g} "
            f"(transformed)")
    scale = {name: layers for (name, *_), (layers, _) in zip(measured, _fit_all(scale_tasks, pool))}
    return LearntLikelihood(unknowns, tuple(configurations), levels, fingerprint, mean, std, classifiers[0][0],
                            location[0], scale, info,
                            tuple(Member(layers, location[k]) for k, (layers, _) in enumerate(classifiers) if k))
