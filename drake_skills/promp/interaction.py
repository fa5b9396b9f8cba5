"""Interaction ProMPs: a Gaussian over stacked human and robot weights.

The weight vector is ``w = [w_h; w_r]`` with ``w_h`` the ``D_h * N_h`` human
weights and ``w_r`` the ``D_r * N_r`` robot weights, each stacked per
dimension (Eq. 4).  Human and robot have their own basis (a 7-joint robot
trajectory needs more basis functions than a wrist path).  Conditioning on
observed human samples is Eq. (13) with the observation matrix ``H_t`` over
the human rows and the observed phases only, so a prefix of the motion works.

The linear algebra of Eq. (13) is done in the ``D_h * N_h``-dimensional human
weight space, never in the ``T_obs * D_h`` observation space: with
``G = H H^T = I_D (x) Phi_o^T Phi_o``, ``S = Sigma_hh`` and ``u = H r``,
the push-through identity gives

    H (sigma^2 I + H^T S H)^{-1}     = (sigma^2 I + G S)^{-1} H
    mu_new    = mu + Sigma_{:,h} (sigma^2 I + G S)^{-1} u
    Sigma_new = Sigma - Sigma_{:,h} (sigma^2 I + G S)^{-1} G Sigma_{h,:}

which equals Eq. (13) exactly and costs O(T_obs D_h N_h + (D_h N_h)^3).
"""
from __future__ import annotations

import numpy as np

from drake_skills._checks import as_finite_array, check_positive
from drake_skills.promp.basis import GaussianBasis, phases, ridge_weights, trajectory_covariance
from drake_skills.promp.gaussian import check_random_state, cholesky, symmetrize

_LOG_2PI = np.log(2.0 * np.pi)


def _blocks(M: np.ndarray, D: int) -> np.ndarray:
    """``np.kron(np.eye(D), M)``: ``D`` copies of ``M`` (n, k) on the diagonal of a (D n, D k) matrix.

    Written out because ``np.kron`` costs several times more at these sizes (3 x (15 x 15): 48 us
    against a few on one machine), and conditioning builds one per call.
    """
    n, k = M.shape
    out = np.zeros((D * n, D * k))
    for d in range(D):
        out[d * n:(d + 1) * n, d * k:(d + 1) * k] = M
    return out


def _observation_terms(mean_h, cov_hh, Phi_o, y_obs, noise_var):
    """Shared pieces of conditioning and the marginal likelihood.

    Returns ``G (h, h)``, ``u = H r (h,)``, ``r (m, D)``, ``A = sigma^2 I + G S``.
    """
    D = y_obs.shape[1]
    N = Phi_o.shape[1]
    PtP = Phi_o.T @ Phi_o
    G = _blocks(PtP, D)
    r = y_obs - Phi_o @ mean_h.reshape(D, N).T  # (m, D) residual of the prior mean
    u = (Phi_o.T @ r).T.reshape(-1)  # H r, stacked per dimension
    A = noise_var * np.eye(D * N) + G @ cov_hh
    return G, u, r, A


def condition_on_observations(mean, cov, Phi_o, y_obs, noise_var: float, *, start: int = 0):
    """Condition ``N(mean, cov)`` over ``[w_h; ...]`` on observed human samples (Eq. 13).

    Parameters
    ----------
    mean : array, shape (d,)
        Stacked weights; the first ``D * N`` entries are the observed agent's.
    cov : array, shape (d, d)
    Phi_o : array, shape (m, N)
        Human basis at the observed phases.
    y_obs : array, shape (m, D)
        Observed human positions.
    noise_var : float
        Observation noise variance sigma_o (Sigma_o = sigma_o I).
    start : int
        Return only the posterior of the weights ``start:`` (e.g. the robot's,
        ``start = D_h * N_h``), which skips the rest of the covariance update.

    Returns
    -------
    mean_new : array, shape (d - start,)
    cov_new : array, shape (d - start, d - start)
    """
    h = y_obs.shape[1] * Phi_o.shape[1]
    return condition_blocks(mean[:h], mean[start:], cov[:h, :h], cov[start:, :h], cov[start:, start:], Phi_o,
                            y_obs, noise_var)


def condition_blocks(mean_h, mean_x, cov_hh, cov_xh, cov_xx, Phi_o, y_obs, noise_var: float):
    """:func:`condition_on_observations` from the blocks it reads: the posterior of other weights ``x``.

    ``mean_h`` (h,), ``cov_hh`` (h, h): the observed agent's prior; ``mean_x`` (n,), ``cov_xh`` (n, h),
    ``cov_xx`` (n, n): the weights whose posterior is returned, and their covariance with the observed
    ones. A caller that holds the blocks need not assemble the whole (d, d) covariance.

    Returns
    -------
    mean_new : array, shape (n,)
    cov_new : array, shape (n, n)
    """
    G, u, _, A = _observation_terms(mean_h, cov_hh, Phi_o, y_obs, noise_var)
    X = np.linalg.solve(A, np.column_stack([u, G]))   # A^-1 u and A^-1 G from one factorization
    mean_new = mean_x + cov_xh @ X[:, 0]
    cov_new = cov_xx - (cov_xh @ X[:, 1:]) @ cov_xh.T
    return mean_new, symmetrize(cov_new)


def conditioned_mean_shift(mean_h, cov_hh, cov_xh, Phi_o, y_obs, noise_var: float) -> np.ndarray:
    """How far Eq. (13) moves the mean of other weights ``x``: ``mean_x_new - mean_x``, shape (n_x,).

    ``cov_hh`` (h, h) and ``cov_xh`` (n_x, h) are blocks of the prior covariance; the
    shift equals ``condition_on_observations(...)[0] - mean[start:]`` without computing
    the posterior covariance (what learning needs, ``library.gain``).
    """
    _, u, _, A = _observation_terms(mean_h, cov_hh, Phi_o, y_obs, noise_var)
    return cov_xh @ np.linalg.solve(A, u)


def observation_log_likelihood(mean_h, cov_hh, Phi_o, y_obs, noise_var: float):
    """Marginal ``log N(vec(y_obs) | H^T mu_h, sigma^2 I + H^T Sigma_hh H)``.

    Returns
    -------
    loglik : float
    d2 : float
        Squared Mahalanobis distance of the observations (chi-square with
        ``m * D`` degrees of freedom under the model).
    n_obs : int
        ``m * D``, the number of observed scalars.
    """
    G, u, r, A = _observation_terms(mean_h, cov_hh, Phi_o, y_obs, noise_var)
    m = r.size
    a = np.linalg.solve(A, u)  # H (sigma^2 I + H^T S H)^{-1} r
    d2 = (np.sum(r * r) - u @ cov_hh @ a) / noise_var
    sign, logdet = np.linalg.slogdet(np.eye(G.shape[0]) + cov_hh @ G / noise_var)
    loglik = -0.5 * (m * (_LOG_2PI + np.log(noise_var)) + logdet + d2)
    return float(loglik), float(d2), int(m)


#: The share of the largest eigenvalue of ``Phi_o^T Phi_o`` a direction of the weights needs
#: for the prefix fit statistic to count it (:func:`prefix_statistics`). Chosen on the
#: buetepage training split by internal validation (right answers at 30 / 40 / 50 % of the
#: path: 0.59 / 0.67 / 0.60 with every spanned direction, 0.67 / 0.88 / 0.96 at 1e-3, 0.80 /
#: 0.93 / 1.0 at 2e-3 and 3e-3, 0.84 / 0.93 / 1.0 at 0.01-0.1) under the constraint that
#: beginnings of untaught synthetic skills are committed to no more often than with every
#: direction (3 of 24 banks; 2 at 1e-3 and 2e-3, 4 at 3e-3, 7 at 0.01, 18 at 0.03;
#: ``benchmarks/seen_rcond.py``).
#: With the default basis a whole motion keeps 6 of 7 directions per dimension, half of
#: one 4, a tenth 2.
SEEN_RCOND = 2e-3


def prefix_statistics(mean_h, cov_hh, Phi_o, y_obs, noise_var: float, seen_rcond: float | None = None):
    """Marginal likelihood of observed human samples, and a chi-square statistic of their fit.

    Under ``vec(y) ~ N(H^T mu_h, sigma^2 I + H^T Sigma_hh H)``:

    * ``loglik``: the marginal log-likelihood of all the samples (as
      :func:`observation_log_likelihood`);
    * ``d2``: the squared Mahalanobis distance of the least-squares weights of the samples
      from ``mu_h``, in the directions of each dimension's weights the samples *see well*:
      the eigenvectors ``V`` of ``Phi_o^T Phi_o`` whose eigenvalues ``g`` are at least
      ``seen_rcond`` of the largest. In the coordinates ``x = (I_D (x) g^{-1/2} V^T) H r``
      (``r`` the residual of the prior mean, ``H r`` stacked per dimension) the misfit has
      covariance ``sigma^2 I + V_g^T Sigma_hh V_g`` with ``V_g = I_D (x) V g^{1/2}``;
      ``d2 = x^T (sigma^2 I + V_g^T Sigma_hh V_g)^{-1} x``;
    * ``dof``: ``D n``, ``n >= 1`` the directions kept per dimension (the best-seen one
      always is); ``d2`` is exactly
      chi-square with ``dof`` degrees of freedom under the model.

    Why not every direction the basis spans (``seen_rcond`` near 0, what this used before,
    at the pseudo-inverse's 1e-10): the residual of a real path is smooth, not white, and in
    the directions the samples barely see (at half a motion, the last basis functions
    through their nearly collinear tails) the least-squares weights amplify it into a
    rejection of the right skill (buetepage_hr: own-component ``d2`` 29-56 at 50 % of the
    path against a threshold of 38-47, and above 90 for some beginnings of the training
    split). Directions outside the basis (fit and sensor noise, whose samples are far from
    independent) were never counted. A statistic over the directions where the prior's
    variance exceeds the noise's would drop those too, but it tests nothing for a skill
    tighter than the noise, whatever the samples.

    ``seen_rcond``: the share (default :data:`SEEN_RCOND`, read at the call). "Exact under
    the model" is at the phase and sample count given; recognition chooses the phase per
    component from the samples, as before.

    Returns
    -------
    loglik : float
    d2 : float
    dof : float
    """
    G, u, r, A = _observation_terms(mean_h, cov_hh, Phi_o, y_obs, noise_var)
    m = r.size
    h = G.shape[0]
    Ainv = np.linalg.inv(A)
    a = Ainv @ u
    explained = u @ cov_hh @ a
    d2_obs = (np.sum(r * r) - explained) / noise_var
    sign, logdet = np.linalg.slogdet(np.eye(h) + cov_hh @ G / noise_var)
    loglik = -0.5 * (m * (_LOG_2PI + np.log(noise_var)) + logdet + d2_obs)
    D = y_obs.shape[1]
    g, V = np.linalg.eigh(Phi_o.T @ Phi_o)
    keep = g >= (SEEN_RCOND if seen_rcond is None else seen_rcond) * g[-1]
    g, V = g[keep], V[:, keep]
    x = _blocks(V / np.sqrt(g), D).T @ u
    Vg = _blocks(V * np.sqrt(g), D)
    C = noise_var * np.eye(x.size) + Vg.T @ cov_hh @ Vg
    d2 = float(x @ np.linalg.solve(C, x))
    return float(loglik), d2, float(x.size)


class InteractionProMP:
    """A Gaussian over stacked human and robot ProMP weights ``[w_h; w_r]``.

    Parameters
    ----------
    dim_human : int
        D_h, dimensions of the observed agent.
    dim_robot : int
        D_r, dimensions of the controlled agent (0 for a human-only ProMP).
    basis_human, basis_robot : GaussianBasis
    ridge : float
        Ridge factor of the weight regression (Eq. 3).
    observation_noise : float
        sigma_o of Eq. (13), the variance of an observed human sample, in the
        units of the human trajectory (normalized units squared in the library).

    Attributes
    ----------
    mean_ : array, shape (D_h N_h + D_r N_r,)
    cov_ : array, shape (d, d)
    n_demos_ : int
    """

    def __init__(self, dim_human: int, dim_robot: int = 0, *, basis_human: GaussianBasis | None = None,
                 basis_robot: GaussianBasis | None = None, ridge: float = 1e-6,
                 observation_noise: float = 0.25):
        if int(dim_human) < 1 or int(dim_robot) < 0:
            raise ValueError(f"need dim_human >= 1 and dim_robot >= 0, got {dim_human}, {dim_robot}")
        self.dim_human = int(dim_human)
        self.dim_robot = int(dim_robot)
        self.basis_human = basis_human or GaussianBasis(10)
        self.basis_robot = basis_robot or GaussianBasis(20)
        self.ridge = float(ridge)
        self.observation_noise = check_positive(observation_noise, "observation_noise")

    # -- sizes -------------------------------------------------------------
    @property
    def n_human(self) -> int:
        """Number of human weights, D_h * N_h."""
        return self.dim_human * self.basis_human.n_basis

    @property
    def n_robot(self) -> int:
        """Number of robot weights, D_r * N_r."""
        return self.dim_robot * self.basis_robot.n_basis

    @property
    def n_weights(self) -> int:
        return self.n_human + self.n_robot

    def _check_fitted(self):
        if not hasattr(self, "mean_"):
            raise ValueError("this InteractionProMP is not fitted yet: call fit() or from_moments()")

    # -- weights -----------------------------------------------------------
    def weights(self, human, robot=None) -> np.ndarray:
        """Stacked weights of one demonstration sampled at uniform phases.

        Parameters
        ----------
        human : array, shape (T_h, D_h)
        robot : array, shape (T_r, D_r), required iff dim_robot > 0

        Returns
        -------
        w : array, shape (n_weights,)
        """
        human = as_finite_array(human, "human trajectory", shape=(None, self.dim_human), min_rows=2)
        parts = [ridge_weights(human, self.basis_human, self.ridge)]
        if self.dim_robot:
            if robot is None:
                raise ValueError("this InteractionProMP has a robot part: pass the robot trajectory")
            robot = as_finite_array(robot, "robot trajectory", shape=(None, self.dim_robot), min_rows=2)
            parts.append(ridge_weights(robot, self.basis_robot, self.ridge))
        elif robot is not None:
            raise ValueError("this InteractionProMP is human-only (dim_robot=0) but a robot trajectory was given")
        return np.concatenate(parts)

    def fit(self, humans, robots=None) -> "InteractionProMP":
        """Maximum-likelihood fit from demonstrations sampled at uniform phases.

        Parameters
        ----------
        humans : sequence of arrays, shape (T, D_h)
        robots : sequence of arrays, shape (T, D_r), or None

        Returns
        -------
        self
        """
        if len(humans) < 1:
            raise ValueError("fit needs at least one demonstration")
        if robots is None:
            robots = [None] * len(humans)
        if len(robots) != len(humans):
            raise ValueError(f"{len(humans)} human but {len(robots)} robot trajectories")
        W = np.stack([self.weights(h, r) for h, r in zip(humans, robots)])
        return self.fit_weights(W)

    def fit_weights(self, W, *, min_variance: float = 1e-6) -> "InteractionProMP":
        """ML mean and (biased) covariance of stacked weights ``W (n, d)``.

        ``min_variance`` is added to the diagonal so that a fit from fewer
        demonstrations than dimensions stays positive definite.
        """
        W = as_finite_array(W, "weights", shape=(None, self.n_weights), min_rows=1)
        mean = W.mean(axis=0)
        diff = W - mean
        cov = diff.T @ diff / W.shape[0] + min_variance * np.eye(self.n_weights)
        return self._set(mean, cov, W.shape[0])

    @classmethod
    def from_moments(cls, mean, cov, dim_human: int, dim_robot: int = 0, **kwargs) -> "InteractionProMP":
        """Wrap given weight moments (e.g. a library component)."""
        p = cls(dim_human, dim_robot, **kwargs)
        mean = as_finite_array(mean, "mean", shape=(p.n_weights,))
        cov = as_finite_array(cov, "covariance", shape=(p.n_weights, p.n_weights))
        return p._set(mean, cov, 0)

    def _set(self, mean, cov, n):
        self.mean_ = mean
        self.cov_ = symmetrize(cov)
        self.n_demos_ = n
        return self

    # -- trajectories -------------------------------------------------------
    def _split_traj(self, n_steps: int):
        self._check_fitted()
        h = self.n_human
        return h, self.basis_human.phi_uniform(n_steps), self.basis_robot.phi_uniform(n_steps)

    def human_distribution(self, n_steps: int = 100):
        """Human trajectory mean (T, D_h) and per-step covariance (T, D_h, D_h)."""
        h, Phi_h, _ = self._split_traj(n_steps)
        mean = Phi_h @ self.mean_[:h].reshape(self.dim_human, -1).T
        cov = trajectory_covariance(self.cov_[:h, :h], self.basis_human, self.dim_human, n_steps=n_steps)
        return mean, cov

    def robot_distribution(self, n_steps: int = 100):
        """Robot trajectory mean (T, D_r) and per-step covariance (T, D_r, D_r)."""
        if not self.dim_robot:
            raise ValueError("this InteractionProMP has no robot part (dim_robot=0)")
        h, _, Phi_r = self._split_traj(n_steps)
        mean = Phi_r @ self.mean_[h:].reshape(self.dim_robot, -1).T
        cov = trajectory_covariance(self.cov_[h:, h:], self.basis_robot, self.dim_robot, n_steps=n_steps)
        return mean, cov

    def sample(self, n: int, n_steps: int = 100, random_state=None):
        """Sample ``n`` trajectory pairs.

        Returns
        -------
        human : array, shape (n, n_steps, D_h)
        robot : array, shape (n, n_steps, D_r) (empty last axis if dim_robot=0)
        """
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"sample: n must be a positive integer, got {n!r}")
        h, Phi_h, Phi_r = self._split_traj(n_steps)
        rng = check_random_state(random_state)
        L = cholesky(self.cov_)
        W = self.mean_ + rng.standard_normal((n, self.n_weights)) @ L.T
        human = np.einsum("tn,kdn->ktd", Phi_h, W[:, :h].reshape(n, self.dim_human, -1))
        robot = np.einsum("tn,kdn->ktd", Phi_r, W[:, h:].reshape(n, self.dim_robot, -1))
        return human, robot

    # -- conditioning (Eq. 13) ----------------------------------------------
    def _observations(self, human_obs, z_obs):
        y = as_finite_array(human_obs, "observed human samples", shape=(None, self.dim_human), min_rows=1)
        z = as_finite_array(z_obs, "observed phases", shape=(y.shape[0],))
        return y, self.basis_human.phi(z)

    def condition(self, human_obs, z_obs, observation_noise: float | None = None) -> "InteractionProMP":
        """Posterior given human samples ``human_obs (m, D_h)`` at phases ``z_obs (m,)`` (Eq. 13).

        Returns a new InteractionProMP; this one is unchanged.
        """
        self._check_fitted()
        y, Phi_o = self._observations(human_obs, z_obs)
        noise = self.observation_noise if observation_noise is None else check_positive(
            observation_noise, "observation_noise")
        mean, cov = condition_on_observations(self.mean_, self.cov_, Phi_o, y, noise)
        post = InteractionProMP(self.dim_human, self.dim_robot, basis_human=self.basis_human,
                                basis_robot=self.basis_robot, ridge=self.ridge, observation_noise=noise)
        return post._set(mean, cov, self.n_demos_)

    def condition_prefix(self, human_prefix, observed_fraction: float = 1.0,
                         observation_noise: float | None = None) -> "InteractionProMP":
        """Condition on samples at evenly spaced phases over ``[0, observed_fraction]``.

        ``human_prefix (m, D_h)`` must already be resampled (e.g. by arc length)
        so that its samples are evenly spaced over that phase interval.
        """
        f = float(observed_fraction)
        if not 0 < f <= 1:
            raise ValueError(f"observed_fraction must be in (0, 1], got {observed_fraction!r}")
        y = as_finite_array(human_prefix, "observed human samples", shape=(None, self.dim_human), min_rows=2)
        return self.condition(y, np.linspace(0.0, f, y.shape[0]), observation_noise)

    def log_likelihood_human(self, human_obs, z_obs, observation_noise: float | None = None,
                             cov_floor: float = 0.0):
        """Marginal log-likelihood of human samples, their Mahalanobis d^2, and m*D_h.

        ``cov_floor`` is added to the diagonal of the human weight covariance.
        """
        self._check_fitted()
        y, Phi_o = self._observations(human_obs, z_obs)
        noise = self.observation_noise if observation_noise is None else check_positive(
            observation_noise, "observation_noise")
        if not np.isfinite(cov_floor) or cov_floor < 0:
            raise ValueError(f"cov_floor must be >= 0, got {cov_floor!r}")
        h = self.n_human
        S = self.cov_[:h, :h] + cov_floor * np.eye(h)
        return observation_log_likelihood(self.mean_[:h], S, Phi_o, y, noise)

    def predict_robot(self, human_obs, z_obs=None, *, n_steps: int = 100, observation_noise: float | None = None):
        """Robot trajectory distribution given observed human samples.

        ``z_obs`` defaults to evenly spaced phases over [0, 1] (the full motion),
        which needs at least 2 samples.

        Returns
        -------
        mean : array, shape (n_steps, D_r)
        cov : array, shape (n_steps, D_r, D_r)
        """
        if z_obs is None:
            human_obs = as_finite_array(human_obs, "observed human samples", shape=(None, self.dim_human),
                                        min_rows=2)
            z_obs = phases(human_obs.shape[0])
        return self.condition(human_obs, z_obs, observation_noise).robot_distribution(n_steps)
