"""COIK: the paper's constrained-optimisation baseline (eq. 16), built once with Drake's MathematicalProgram.

The program over the 18 arm coordinates ``p = [ps_l, pe_l, pw_l, ps_r, pe_r, pw_r]`` (camera frame C,
metres) is

.. code-block:: text

    min_p   |p - p_hat|^2 + lam |p - p_prev|^2
    s.t.    |pe_j - pw_j|^2 = lf_j^2,  |ps_j - pe_j|^2 = lu_j^2          (j in {l, r})
            theta_min <= theta(ps_j, pe_j, pw_j) <= theta_max
            |ps_l - ps_r|^2 = ls^2

It is built ONCE: the cost is a single :class:`pydrake.solvers.QuadraticCost` whose linear and constant terms
are updated every frame (the Hessian ``2 (1 + lam) I`` never changes), and every constraint is a
:class:`pydrake.solvers.QuadraticConstraint` that Drake evaluates in C++ (no Python callbacks). With the
length equalities holding, ``cos(theta) = (s - e).(w - e) / (lu lf)``, so the elbow-angle bound is the
quadratic constraint ``cos(theta_max) lu lf <= (s - e).(w - e) <= cos(theta_min) lu lf`` (the lower side is
dropped when ``theta_max`` is 180 deg, where it holds for any point).

This is the one module of :mod:`akc_drake.core` that imports Drake.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from pydrake.solvers import (
    IpoptSolver,
    MathematicalProgram,
    NloptSolver,
    QuadraticConstraint,
    SnoptSolver,
    SolutionResult,
    SolverOptions,
)

from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS, BodyDimensions, check_pose
from akc_drake.errors import UserError

#: Solver names accepted by :class:`COIKConfig`.
SOLVERS: tuple[str, ...] = ("snopt", "ipopt", "nlopt")

_SOLVER_CLASSES = {"snopt": SnoptSolver, "ipopt": IpoptSolver, "nlopt": NloptSolver}

#: Status strings of :class:`COIKResult` and their numeric codes (the LeafSystem's ``diagnostics[0]``).
#: ``held``: nothing to solve (no finite arm coordinate, or missing coordinates and no previous solution);
#: the previous output is held (NaN when there is none).
STATUS_CODES: dict[str, int] = {"success": 0, "iteration_limit": 1, "infeasible": 2, "failed": 3, "held": 4}
STATUSES: tuple[str, ...] = tuple(STATUS_CODES)

#: Landmark index of each of the six points of ``p``, in the order of eq. (16).
P_LANDMARKS: tuple[str, ...] = (
    "left_shoulder",
    "left_elbow",
    "left_wrist",
    "right_shoulder",
    "right_elbow",
    "right_wrist",
)
P_INDICES: np.ndarray = np.array([INDEX[n] for n in P_LANDMARKS], dtype=np.intp)
NUM_P = 3 * len(P_LANDMARKS)

#: Size of :meth:`COIKSolver.get_state_vector`: the previous solution (18) and a has-previous flag.
STATE_SIZE = NUM_P + 1


class COIKOptionError(UserError, ValueError):
    """A bad COIK option (unknown or unavailable solver, out-of-range value). Both a ``UserError`` and a
    ``ValueError``, so the CLI reports it in one line and library callers can catch ``ValueError``."""


def available_solvers() -> tuple[str, ...]:
    """The names in :data:`SOLVERS` whose Drake solver is available and enabled in this installation."""
    out = []
    for name in SOLVERS:
        solver = _SOLVER_CLASSES[name]()
        if solver.available() and solver.enabled():
            out.append(name)
    return tuple(out)


def status_from_solution_result(result: SolutionResult) -> str:
    """Map Drake's :class:`~pydrake.solvers.SolutionResult` to a COIK status string."""
    if result == SolutionResult.kSolutionFound:
        return "success"
    if result == SolutionResult.kIterationLimit:
        return "iteration_limit"
    if result in (SolutionResult.kInfeasibleConstraints, SolutionResult.kInfeasibleOrUnbounded):
        return "infeasible"
    return "failed"


@dataclass(frozen=True)
class COIKConfig:
    """Options of the COIK program (eq. 16).

    Attributes:
        lam: temporal weight λ on ``|p - p_prev|^2`` (>= 0).
        solver: ``"snopt"`` | ``"ipopt"`` | ``"nlopt"``.
        iteration_limit: SNOPT "Major iterations limit", IPOPT "max_iter", NLopt "max_eval" (NLopt counts
            function evaluations, not iterations).
        elbow_min_deg, elbow_max_deg: bounds of the elbow angle θ (angle at the elbow between the upper arm
            and the forearm; 180 deg = straight arm), 0 <= min < max <= 180.
        constraint_tol: the solver's constraint-feasibility tolerance (SNOPT "Major feasibility tolerance",
            IPOPT "constr_viol_tol", NLopt "constraint_tol"), on the squared-length constraints in m^2.
        warm_start: start each solve from the previous solution (True) or from the (NaN-filled) reference
            ``p_hat`` (False). The first frame always starts from ``p_hat``.
    """

    lam: float = 0.5
    solver: str = "snopt"
    iteration_limit: int = 100
    elbow_min_deg: float = 40.0
    elbow_max_deg: float = 180.0
    constraint_tol: float = 1e-10
    warm_start: bool = True

    def __post_init__(self):
        if self.solver not in SOLVERS:
            raise COIKOptionError(
                f"COIKConfig.solver must be one of {', '.join(SOLVERS)}, got {self.solver!r}"
            )
        lam = float(self.lam)
        if not math.isfinite(lam) or lam < 0.0:
            raise COIKOptionError(f"COIKConfig.lam must be a finite number >= 0, got {self.lam!r}")
        object.__setattr__(self, "lam", lam)
        if isinstance(self.iteration_limit, bool) or not isinstance(self.iteration_limit, (int, np.integer)):
            raise COIKOptionError(
                f"COIKConfig.iteration_limit must be an integer, got {self.iteration_limit!r}"
            )
        if self.iteration_limit < 1:
            raise COIKOptionError(f"COIKConfig.iteration_limit must be >= 1, got {self.iteration_limit!r}")
        lo, hi = float(self.elbow_min_deg), float(self.elbow_max_deg)
        if not (0.0 <= lo < hi <= 180.0):
            raise COIKOptionError(
                f"COIKConfig elbow bounds must satisfy 0 <= elbow_min_deg < elbow_max_deg <= 180, "
                f"got elbow_min_deg={self.elbow_min_deg!r}, elbow_max_deg={self.elbow_max_deg!r}"
            )
        tol = float(self.constraint_tol)
        if not math.isfinite(tol) or tol <= 0.0:
            raise COIKOptionError(
                f"COIKConfig.constraint_tol must be a positive number, got {self.constraint_tol!r}"
            )


@dataclass(frozen=True)
class COIKResult:
    """One COIK frame.

    Attributes:
        pose: ``(12, 3)`` the input pose with the six arm joints replaced by the solution (or the held
            output).
        status: one of :data:`STATUSES`. On ``iteration_limit``/``infeasible``/``failed`` the pose holds
            the solver's last iterate, as the paper describes (or the previous output if that iterate is not
            finite).
        solve_time_s: wall time of the solver call (0 when nothing was solved).
        solver: solver name.
        max_length_error_m: largest ``| |segment| - calibrated length |`` over LUA, LLA, RUA, RLA, SW of the
            output, metres (NaN when the output arm joints are NaN).
    """

    pose: np.ndarray
    status: str
    solve_time_s: float
    solver: str
    max_length_error_m: float = field(default=float("nan"))

    @property
    def status_code(self) -> int:
        """Numeric status (:data:`STATUS_CODES`)."""
        return STATUS_CODES[self.status]


def _pair_hessian() -> np.ndarray:
    """Q such that 0.5 [a; b]^T Q [a; b] = |a - b|^2 for a, b in R^3."""
    eye = np.eye(3)
    return 2.0 * np.block([[eye, -eye], [-eye, eye]])


def _angle_hessian() -> np.ndarray:
    """Q such that 0.5 [s; e; w]^T Q [s; e; w] = (s - e).(w - e) for s, e, w in R^3."""
    eye, zero = np.eye(3), np.zeros((3, 3))
    return np.block([[zero, -eye, eye], [-eye, 2.0 * eye, -eye], [eye, -eye, zero]])


#: For each arm joint row of ``p`` (shoulder, elbow, wrist), the rows whose depth stands in for a missing one.
_DEPTH_DONORS = {0: (1, 2), 1: (2, 0), 2: (1, 0)}


def _fill_missing_depths(p_hat: np.ndarray, dims: BodyDimensions) -> np.ndarray:
    """``p_hat`` (18,) with each missing z (x, y known) rebuilt from the nearest joint of the same arm.

    A depth goes missing because the joint is hidden behind a more distal part of its arm, so it lies farther
    from the camera than the joint that hides it: ``z = z_donor + sqrt(l^2 - dxy^2)`` with ``l`` the length
    between the two joints (0 when the image distance already exceeds it). Only a reference for the first
    frame: the length constraints then place the joint.
    """
    P = p_hat.reshape(6, 3).copy()
    for arm, side in ((0, "left"), (3, "right")):
        lu, lf = dims.upper(side), dims.lower(side)
        length = {(0, 1): lu, (1, 0): lu, (1, 2): lf, (2, 1): lf, (0, 2): lu + lf, (2, 0): lu + lf}
        for j, donors in _DEPTH_DONORS.items():
            row = P[arm + j]
            if np.isfinite(row[:2]).all() and not np.isfinite(row[2]):
                for d in donors:
                    donor = P[arm + d]
                    if np.isfinite(donor).all():
                        dxy2 = float((row[0] - donor[0]) ** 2 + (row[1] - donor[1]) ** 2)
                        sign = 1.0 if j < d else -1.0  # a proximal joint hides behind a distal one
                        row[2] = donor[2] + sign * math.sqrt(max(length[(j, d)] ** 2 - dxy2, 0.0))
                        break
    return P.reshape(-1)


class COIKSolver:
    """Solves eq. (16) frame by frame, warm-started from the previous solution.

    Args:
        dims: the calibrated arm lengths and shoulder width.
        config: program and solver options.

    Raises:
        COIKOptionError: the chosen solver is not available in this Drake installation.
    """

    def __init__(self, dims: BodyDimensions, config: COIKConfig | None = None):
        if not isinstance(dims, BodyDimensions):
            raise ValueError(f"dims must be a BodyDimensions, got {type(dims).__name__}")
        self.dims = dims
        self.config = config if config is not None else COIKConfig()
        cfg = self.config
        solver = _SOLVER_CLASSES[cfg.solver]()
        if not (solver.available() and solver.enabled()):
            avail = available_solvers()
            raise COIKOptionError(
                f"COIK solver {cfg.solver!r} is not available in this Drake installation; "
                f"available: {', '.join(avail) if avail else 'none'}"
            )
        self._solver = solver
        self._options = SolverOptions()
        sid = solver.solver_id()
        if cfg.solver == "snopt":
            self._options.SetOption(sid, "Major iterations limit", int(cfg.iteration_limit))
            self._options.SetOption(sid, "Major feasibility tolerance", float(cfg.constraint_tol))
        elif cfg.solver == "ipopt":
            self._options.SetOption(sid, "max_iter", int(cfg.iteration_limit))
            self._options.SetOption(sid, "constr_viol_tol", float(cfg.constraint_tol))
            self._options.SetOption(sid, "print_level", 0)
        else:
            self._options.SetOption(sid, NloptSolver.MaxEvalName(), int(cfg.iteration_limit))
            self._options.SetOption(sid, NloptSolver.ConstraintToleranceName(), float(cfg.constraint_tol))

        self._build_program()
        self._prev = np.full(NUM_P, np.nan)
        self._has_prev = False

    # ------------------------------------------------------------------ program
    def _build_program(self) -> None:
        d, cfg = self.dims, self.config
        prog = MathematicalProgram()
        p = prog.NewContinuousVariables(NUM_P, "p")
        self._prog, self._p = prog, p

        def point(k: int) -> np.ndarray:
            return p[3 * k : 3 * k + 3]

        # Cost of eq. (16): |p - p_hat|^2 + lam |p - p_prev|^2 = 0.5 p^T Q p + b^T p + c with
        # Q = 2 (1 + lam) I, b = -2 (p_hat + lam p_prev), c = |p_hat|^2 + lam |p_prev|^2 (b, c set per frame).
        self._Q = 2.0 * (1.0 + cfg.lam) * np.eye(NUM_P)
        self._cost = prog.AddQuadraticCost(self._Q, np.zeros(NUM_P), 0.0, p, is_convex=True).evaluator()

        psd = QuadraticConstraint.HessianType.kPositiveSemidefinite
        pair_q, angle_q, zeros6 = _pair_hessian(), _angle_hessian(), np.zeros(6)
        cos_min = math.cos(math.radians(cfg.elbow_min_deg))
        cos_max = math.cos(math.radians(cfg.elbow_max_deg))
        self._targets = []  # (point a, point b, length) for the length-error diagnostic
        for side, (s, e, w) in (("left", (0, 1, 2)), ("right", (3, 4, 5))):
            lf, lu = d.lower(side), d.upper(side)
            # Eq. (16): |p_e - p_w|^2 = l_f^2
            prog.AddQuadraticConstraint(
                pair_q, zeros6, lf**2, lf**2, np.concatenate([point(e), point(w)]), psd
            )
            # Eq. (16): |p_s - p_e|^2 = l_u^2
            prog.AddQuadraticConstraint(
                pair_q, zeros6, lu**2, lu**2, np.concatenate([point(s), point(e)]), psd
            )
            # Eq. (16): theta_min <= theta <= theta_max, as cos(theta_max) lu lf <= (s-e).(w-e) <=
            # cos(theta_min) lu lf
            ub = cos_min * lu * lf if cfg.elbow_min_deg > 0.0 else np.inf
            lb = cos_max * lu * lf if cfg.elbow_max_deg < 180.0 else -np.inf
            prog.AddQuadraticConstraint(
                angle_q,
                np.zeros(9),
                lb,
                ub,
                np.concatenate([point(s), point(e), point(w)]),
                QuadraticConstraint.HessianType.kIndefinite,
            )
            self._targets += [(e, w, lf), (s, e, lu)]
        # Eq. (16): |p_s,l - p_s,r|^2 = l_s^2
        prog.AddQuadraticConstraint(
            pair_q, zeros6, d.SW**2, d.SW**2, np.concatenate([point(0), point(3)]), psd
        )
        self._targets.append((0, 3, d.SW))

    # -------------------------------------------------------------------- state
    def reset(self) -> None:
        """Forget the previous solution (the next frame is a first frame)."""
        self._prev = np.full(NUM_P, np.nan)
        self._has_prev = False

    @property
    def previous_solution(self) -> np.ndarray | None:
        """The previous output ``p`` (18,), or None before the first solved frame."""
        return self._prev.copy() if self._has_prev else None

    def get_state_vector(self) -> np.ndarray:
        """``[p_prev (18), has_prev]`` for a Drake discrete state."""
        return np.concatenate([np.where(self._has_prev, self._prev, 0.0), [1.0 if self._has_prev else 0.0]])

    def set_state_vector(self, v) -> None:
        """Restore the state written by :meth:`get_state_vector`."""
        v = np.asarray(v, dtype=float)
        if v.shape != (STATE_SIZE,):
            raise ValueError(f"COIK state vector must have shape ({STATE_SIZE},), got {v.shape}")
        self._has_prev = bool(v[-1] > 0.5)
        self._prev = v[:NUM_P].copy() if self._has_prev else np.full(NUM_P, np.nan)

    # -------------------------------------------------------------------- solve
    def length_error(self, p: np.ndarray) -> float:
        """Largest ``| |a - b| - l |`` over the five constrained segments of ``p`` (18,), metres."""
        errs = [
            abs(float(np.linalg.norm(p[3 * a : 3 * a + 3] - p[3 * b : 3 * b + 3])) - ln)
            for a, b, ln in self._targets
        ]
        return max(errs)

    def solve(self, pose) -> COIKResult:
        """Solve eq. (16) for one frame.

        Args:
            pose: ``(12, 3)`` filtered landmarks ``p_hat`` in the camera frame; NaN (or inf) where missing.
                A missing arm coordinate is replaced by the previous solution's; when there is no previous
                solution and a coordinate is missing, or when no arm coordinate is finite, the frame is
                skipped and the previous output held (status ``"held"``).

        Returns:
            COIKResult: the pose with its six arm joints replaced by the solution.
        """
        pose = check_pose(pose)
        out = pose.copy()
        p_hat = pose[P_INDICES].reshape(NUM_P)
        missing = ~np.isfinite(p_hat)
        solver_name = self.config.solver

        if missing.any() and not self._has_prev and not missing.all():
            # First frame with a depth missing (e.g. a shoulder hidden from the start): borrow the depth of the
            # nearest joint on the same arm as the reference; the length constraints then place the joint.
            p_hat = _fill_missing_depths(p_hat, self.dims)
            missing = ~np.isfinite(p_hat)
        if missing.all() or (missing.any() and not self._has_prev):
            held = self._prev if self._has_prev else np.full(NUM_P, np.nan)
            out[P_INDICES] = held.reshape(-1, 3)
            err = self.length_error(held) if self._has_prev else float("nan")
            return COIKResult(out, "held", 0.0, solver_name, err)

        p_hat = np.where(missing, self._prev, p_hat) if missing.any() else p_hat
        p_prev = self._prev if self._has_prev else p_hat
        lam = self.config.lam
        b = -2.0 * (p_hat + lam * p_prev)
        c = float(p_hat @ p_hat + lam * (p_prev @ p_prev))
        self._cost.UpdateCoefficients(self._Q, b, c, True)
        x0 = p_prev if (self.config.warm_start and self._has_prev) else p_hat

        t0 = time.perf_counter()
        try:
            result = self._solver.Solve(self._prog, x0, self._options)
        except RuntimeError:
            result = None
        solve_time = time.perf_counter() - t0

        if result is None:
            status, p = "failed", x0.copy()
        else:
            status = status_from_solution_result(result.get_solution_result())
            # On failure this is the solver's last iterate, which COIK outputs as it is (paper §II-E).
            p = np.asarray(result.GetSolution(self._p), dtype=float)
            if not np.all(np.isfinite(p)):
                status, p = "failed", x0.copy()

        self._prev = p.copy()
        self._has_prev = True
        out[P_INDICES] = p.reshape(-1, 3)
        return COIKResult(out, status, solve_time, solver_name, self.length_error(p))

    def solve_sequence(self, poses) -> tuple[np.ndarray, list[COIKResult]]:
        """Solve every frame of ``poses`` ``(T, 12, 3)`` in order (state carried over); returns the corrected
        trajectory ``(T, 12, 3)`` and the per-frame results."""
        poses = check_pose(poses, name="poses", allow_trajectory=True)
        if poses.ndim == 2:
            poses = poses[None]
        results = [self.solve(frame) for frame in poses]
        return np.stack([r.pose for r in results]) if results else np.empty((0, NUM_LANDMARKS, 3)), results
