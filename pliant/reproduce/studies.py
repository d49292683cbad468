"""The studies: every thesis table and section the project reproduces, declared once.

Ours is never written here: each figure names the committed file and the JSON path that hold it.
Quick variants' times were measured one at a time on the project's 2-core machine while other
jobs loaded it (load average 6-10, 2026-12-06), the first run of each (cold caches): expect less
on a quiet machine (all nine in sequence by `.ci/reproduce-quick`, at load 5-7 with Numba's
cache warm: 249 s).
"""

from __future__ import annotations

from pliant.reproduce.registry import Figure, Quick, Study

_PLANNING = "experiments/results/planning/table_3_1.json"
_TABLE_3_2 = "experiments/results/reduction/table_3_2.json"
_DEBRIS = "experiments/results/rl/trunk_debris_ppo_catchable_course40_bc_1e5/summary.json"
_DEBRIS_OWN_DRAW = "experiments/results/rl/trunk_debris_ppo/summary.json"
_DEBRIS_CATCHABLE = "behaviour cloning then PPO (1e5 steps), catchable placements, success"
_DEBRIS_OWN = "the same policy on the environment's own draw, success"
_CARTSTEM = "experiments/results/rl/cartstem_sac/summary.json"
_SPEED = "experiments/results/proxy_speed_nolag.json"
_SPEED_REFERENCE = "experiments/results/proxy_speed_reference.json"
_MULTIGAIT_PROXY = "experiments/proxy/round1/multigait_calibration.json"
_TRUNK_PROXY = "experiments/proxy/trunk_calibration.json"
_TRANSFER = (
    "experiments/results/proxy/rl_multigait_surface/twin_underside_corrector_prior10/"
    "multigait_transfer.json"
)
_PRIOR_SELECTION = "experiments/results/proxy/prior_selection.json"
_SELECTOR = "experiments/results/graph/selector.json"
_GRAPH = "experiments/results/graph/CartStemContact/summary.json"
_TABLE_5_1 = "experiments/results/condensed/table_5_1.json"
_TABLE_5_1_CORNER = "experiments/results/condensed/table_5_1_diamond_6495.json"
_TABLE_5_1_PROTOCOL = "experiments/results/condensed/table_5_1_diamond_protocol.json"
_TABLE_5_2 = "experiments/results/condensed/table_5_2.json"
_TABLE_5_4 = "experiments/results/condensed/table_5_4_stiff_flop.json"
_TABLE_5_7 = "experiments/results/condensed/table_5_7.json"
_TABLE_5_8 = "experiments/results/condensed/trajectories.json"
_CALIBRATION = "experiments/results/condensed/calibration_finger.json"
_MODELS = "experiments/results/condensed/models"  # the kept condensed models
_TABLE_5_1_MODELS = "experiments/results/condensed/table_5_1_models"  # Table 5.1's, kept
# Why the other condensed networks are not kept (their studies' not_kept).
_NETWORK_SIZE = (
    " A condensed network is 1-2 MB (float32): the repository keeps seven (Table 5.1's Finger"
    " and two protocol networks, Table 5.2's coarse one, Table 5.3's two, the design study's)"
    " besides the RL policies, within the 30 MB its tracked results may take"
)
_TRAJOPT = "experiments/results/trajopt/diamond.json"
_GRIPPER_BC = "experiments/results/rl/gripper_bc/summary.json"
_MAZE = "experiments/results/planning/maze_corners.json"
_ROBUST_TRUNK = "experiments/results/proxy/robustness_trunk.json"
_ROBUST_MULTIGAIT = "experiments/results/proxy/robustness_surface.json"
_CONTACTS = "experiments/results/condensed/contacts/contacts.json"
_DESIGN = "experiments/results/condensed/design/design.json"
_DESIGN_DATA = (
    "640 samples over 80 designs (Length 38-42, Height 20-22, Joint Height 5-8 mm), each meshed"
    " anew, cable 0 pulled 0-10 mm and cable 1 held (the thesis' finger has one cable)"
)
_CONTACTS_QUICK = (
    "python experiments/condensed/contacts.py --finger-samples 16 --gripper-poses 8 --epochs 2"
    " --pushes 2 --goals 2 --iterations 1 --workers 1 --work {out}/work --out {out}"
)
# Table 5.3's re-evaluation: the committed run's held-out, button and circle times on quiet cores
# (18 + 250 + 8 + 46 s); 1 281 s measured beside a SAC run on 2026-12-08, every figure equal.
_CONTACTS_EVALUATE_SECONDS = 322.0
_DESIGN_EVALUATE_SECONDS = 93.0  # 2026-12-08, one niced job beside a SAC run; every figure equal
_FEW_EPOCHS_CONTACTS = "1000 epochs (the thesis' best epochs 42 540 and 38 440)"
_SCENARIOS = ("stiff-flop", "lianford-spiral", "lianford-pick-place", "lianford-orientation")
_ROUTING = "experiments/results/diff/routing.json"
_DIFF_CONTROL = {
    "Diamond": "experiments/results/diff/control.json",
    "Trunk": "experiments/results/diff/control_trunk.json",
}
_DIFF_POLICY = "experiments/results/diff/policy.json"
_REACHABLE = (
    "goals drawn where this Diamond reaches (the effector after random cable displacements"
    " held 8 steps): the environment's own box, SofaGym's, lies mostly outside its workspace;"
    " budgets sized to 50 min on the shared 2-core machine"
)
_LBFGS = "runs/L-BFGS-B + adjoint, no change bound"
_DDP = "runs/box-DDP, no change bound"

_LOADED = "timed on the shared 2-core machine under load (load average 4-11); the ratio holds"
_OUR_MULTIGAIT = (
    "Pliant's default Multigait mesh and command sizes, in mm; the thesis' SofaGym mesh, in cm: "
    "compare the ordering (learned above hand, reduced against full), not the values"
)
_ENGINE = (
    "Pliant's engine on this machine, not SOFA on the thesis' (a quiet run, load average under"
    " 3): the ratios between the rows compare, not the real-time factors"
)
_MULTIGAIT_FIT = (
    "fitted on Pliant's FEM Multigait walking its hand gait (the thesis: SOFA, 16 patterns it"
    " does not list)"
)
_TRUNK_FIT = "four cable phases of our choosing; the cables mapped linearly to the beams' bendings"
_MECHANICAL = (
    "one cable pulled 0-10 mm, the other held; SiLU and a cosine learning rate; F trained 1000"
    " epochs and G 10 000 (the thesis' best epochs 12 530 and 18 420)"
)
_CONDENSED_SAMPLES = "fewer epochs than the thesis' 9000 (1500); W is SOFA's material tangent"
_EPOCH_ON_TEST = (
    "the epoch of least test loss is reported, as the thesis' tables report theirs: a"
    " validation loss (the training keeps the network at its best test epoch); a held-out test"
    " drawn afterwards needs the network, not kept: "
)


def _table_5_2_loss(name: str, path: str, thesis: float, protocol: str) -> Figure:
    """A Table 5.2 loss (a mesh's validation or held-out test loss)."""
    return Figure(
        name,
        _TABLE_5_2,
        path,
        thesis=thesis,
        unit="",
        better="lower",
        tolerance=0.5,
        departure="1000 samples a mesh (thesis 6500), 1000 epochs (thesis 9000)",
        fmt="{:.2e}",
        docs="docs/condensed.md",
        protocol=protocol,
    )


STUDIES: tuple[Study, ...] = (
    Study(
        name="table-3.1",
        thesis="Table 3.1",
        title="Diamond positioning: inverse QP against OPD, same accuracy",
        command="python experiments/planning/table_3_1.py",
        docs="docs/planning.md",
        figures=(
            Figure(
                "inverse QP, mean time to 1 mm",
                _PLANNING,
                "summary/qp_mean_time_to_tolerance_s",
                thesis=3.93,
                unit="s",
                better="lower",
                tolerance=0.5,
                departure=_LOADED + "; the thesis states no tolerance (ours 1 mm)",
                fmt="{:.2f}",
                docs="docs/planning.md",
            ),
            Figure(
                "OPD, mean time to 1 mm",
                _PLANNING,
                "summary/opd_mean_time_s",
                thesis=38.24,
                unit="s",
                better="lower",
                tolerance=0.5,
                departure=_LOADED + " (about 4x); budget 64, which the thesis does not give",
                fmt="{:.0f}",
                docs="docs/planning.md",
            ),
            Figure(
                "OPD, goals reached of 5",
                _PLANNING,
                "summary/opd_reached",
                thesis=None,
                unit="goals",
                better="higher",
                tolerance=0.0,
                fmt="{:.0f}",
            ),
        ),
        quick=Quick(
            "python experiments/planning/table_3_1.py --goals 1 --budget 16"
            " --out {out}/table_3_1.json",
            {_PLANNING: "table_3_1.json"},
            seconds=71.0,
        ),
    ),
    Study(
        name="table-3.2",
        thesis="Table 3.2",
        title="Multigait, 6 steps: hand-defined gait against a gait learned by PPO",
        command=(
            "pliant train pliant/ReducedMultigait-v0 --algo PPO --config"
            " pliant/learn/configs/Multigait.yaml --out runs/table_3_2_ppo --seed 0"
            " && python experiments/reduction/table_3_2.py --run runs/table_3_2_ppo"
            " --keep experiments/results/reduction/table_3_2_policies"
        ),
        docs="docs/reduction.md",
        figures=(
            Figure(
                "hand gait, cumulative reward on the reduced model",
                _TABLE_3_2,
                "hand/reduced/cumulative_reward_mm",
                thesis=5.38,
                unit="mm",
                thesis_unit="cm",
                better="higher",
                tolerance=0.02,
                departure=_OUR_MULTIGAIT,
                fmt="{:.2f}",
                docs="docs/reduction.md",
            ),
            Figure(
                "learned gait, cumulative reward on the reduced model",
                _TABLE_3_2,
                "learned/reduced/cumulative_reward_mm",
                thesis=6.33,
                unit="mm",
                thesis_unit="cm",
                better="higher",
                tolerance=0.1,
                departure=_OUR_MULTIGAIT + "; the learned gait is the best evaluated policy's",
                fmt="{:.2f}",
                docs="docs/reduction.md",
                protocol="the checkpoint is the best of the training's evaluations, which are"
                " this figure's own (one deterministic episode on the reduced model); the final"
                " policy, chosen by nothing, is the next figure",
            ),
            Figure(
                "learned gait, the final policy (no selection), cumulative reward on the reduced"
                " model",
                _TABLE_3_2,
                "final/reduced/cumulative_reward_mm",
                thesis=6.33,
                unit="mm",
                thesis_unit="cm",
                better="higher",
                tolerance=0.1,
                departure=_OUR_MULTIGAIT,
                fmt="{:.2f}",
                protocol="the training run's final policy (10 080 steps), no checkpoint chosen:"
                " still above the hand gait's",
            ),
            Figure(
                "learned gait, the final policy (no selection), final x on the full FEM",
                _TABLE_3_2,
                "final/full/final_travel_mm",
                thesis=6.21,
                unit="mm",
                thesis_unit="cm",
                better="higher",
                tolerance=0.1,
                departure=_OUR_MULTIGAIT,
                fmt="{:.2f}",
                docs="docs/reduction.md",
                protocol="the final policy's gait replayed on the full FEM: chosen by nothing",
            ),
            *(
                Figure(
                    f"{gait} gait, final x on the reduced model",
                    _TABLE_3_2,
                    f"{gait}/reduced/final_travel_mm",
                    thesis=thesis,
                    unit="mm",
                    thesis_unit="cm",
                    better="higher",
                    tolerance=tolerance,
                    departure=_OUR_MULTIGAIT,
                    fmt="{:.2f}",
                    docs="docs/reduction.md",
                    protocol=protocol,
                )
                for gait, thesis, tolerance, protocol in (
                    ("hand", 3.24, 0.02, ""),
                    ("learned", 4.51, 0.1, "the best evaluated checkpoint's gait (see above)"),
                )
            ),
            Figure(
                "hand gait, final x on the full FEM",
                _TABLE_3_2,
                "hand/full/final_travel_mm",
                thesis=3.56,
                unit="mm",
                thesis_unit="cm",
                better="higher",
                tolerance=0.02,
                departure=_OUR_MULTIGAIT,
                fmt="{:.2f}",
                docs="docs/reduction.md",
            ),
            Figure(
                "learned gait, final x on the full FEM",
                _TABLE_3_2,
                "learned/full/final_travel_mm",
                thesis=6.21,
                unit="mm",
                thesis_unit="cm",
                better="higher",
                tolerance=0.1,
                departure=_OUR_MULTIGAIT,
                fmt="{:.2f}",
                docs="docs/reduction.md",
                protocol="the best evaluated checkpoint's gait replayed on the full FEM (chosen"
                " on the reduced model's evaluation, reported on the full FEM: a different"
                " model, but the same single episode)",
            ),
        ),
        # Both policies kept (188 kB each); measured 2026-12-07 at load 5-8: the re-evaluation
        # gave the committed gaits and figures.
        evaluate=Quick(
            "python experiments/reduction/table_3_2.py --evaluate"
            " experiments/results/reduction/table_3_2_policies --out {out}",
            {_TABLE_3_2: "table_3_2.json"},
            seconds=309.0,
        ),
        no_quick="a 64-step PPO run on the reduced Multigait and both gaits replayed on both"
        " models was still building the reduced model (20 training sequences; about 2 min on a"
        " quiet machine, cached in $PLIANT_CACHE) after 8 min at load 8: not minutes (the kept"
        " policies are re-evaluated by --evaluate)",
    ),
    Study(
        name="gripper-bc",
        thesis="§3.2.1, Fig. 3.7, 3.8",
        title="Gripper: recurrent PPO with and without cloning the hand-designed grasp",
        command="python experiments/rl/gripper_bc.py --steps 30000",
        docs="docs/studies/learning.md",
        figures=(
            Figure(
                "from scratch, steps to 80 % success (evaluations every 10 000 steps)",
                _GRIPPER_BC,
                "runs/scratch/steps_to_threshold",
                thesis=1.4e6,
                unit="steps",
                better="lower",
                tolerance=1.0,
                departure="the thesis' 1.4e6 steps are its convergence, read off its curve;"
                " this Gripper is learnt within the first 10 000 steps (8 actions, a success"
                " within 3 mm of the goal height, no push-down force), so the evaluations"
                " every 10 000 steps only bound it",
                fmt="{:,.0f}",
                docs="docs/studies/learning.md",
            ),
            Figure(
                "cloned first, steps to 80 % success (evaluations)",
                _GRIPPER_BC,
                "runs/bc/steps_to_threshold",
                thesis=None,
                unit="steps",
                better="lower",
                tolerance=1.0,
                fmt="{:,.0f}",
                docs="docs/studies/learning.md",
            ),
            *(
                Figure(
                    f"{name}, steps to 80 % success over 20 training episodes in a row",
                    _GRIPPER_BC,
                    f"runs/{key}/training_steps_to_threshold",
                    thesis=None,
                    unit="steps",
                    better="lower",
                    tolerance=1.0,
                    fmt="{:,.0f}",
                    docs="docs/studies/learning.md",
                )
                for name, key in (("from scratch", "scratch"), ("cloned first", "bc"))
            ),
            *(
                Figure(
                    f"{name}, success of the final policy (10 episodes)",
                    _GRIPPER_BC,
                    f"runs/{key}/training/final_evaluation/success_rate",
                    thesis=None,
                    unit="%",
                    better="higher",
                    tolerance=0.2,
                    scale=100.0,
                    fmt="{:.0f}",
                    docs="docs/studies/learning.md",
                    protocol="the final policy, no checkpoint chosen",
                )
                for name, key in (("from scratch", "scratch"), ("cloned first", "bc"))
            ),
        ),
        quick=Quick(
            "python experiments/rl/gripper_bc.py --steps 256 --eval-freq 256 --eval-episodes 1"
            " --bc-epochs 2 --expert-episodes 4 --runs {out}/runs --out {out}",
            {_GRIPPER_BC: "summary.json"},
            seconds=120.0,
            # 256 steps reach no threshold: the steps to it are not written
            figures=(
                "from scratch, success of the final policy (10 episodes)",
                "cloned first, success of the final policy (10 episodes)",
            ),
        ),
        # Both final policies kept (LSTM actors, 0.32 MB each); re-evaluated on 2026-12-08 (12 s):
        # the final evaluations to the last digit.
        evaluate=Quick(
            "python experiments/rl/gripper_bc.py --evaluate experiments/results/rl/gripper_bc"
            " --out {out}",
            {_GRIPPER_BC: "summary.json"},
            seconds=12.0,
            figures=(
                "from scratch, success of the final policy (10 episodes)",
                "cloned first, success of the final policy (10 episodes)",
            ),
        ),
        not_kept="the steps to 80 % are learning speeds, not a policy's: re-made by the"
        " study's command (two runs of 30 000 steps, about 9 min each on the shared machine)",
    ),
    Study(
        name="trunk-debris",
        thesis="§3.2.2",
        title="Trunk whole-arm grasp of space debris by PPO, success over 400 tests",
        command=(
            "python experiments/rl/trunk_debris_ppo.py --steps 102400 --tests 400 --variant"
            " catchable_course40 --workers 1 --bc --bc-epochs 1000 --learning-rate 3e-5"
            " --target-kl 0.02 --tag 1e5 --own-draw-tests 400"
            " && python experiments/rl/trunk_debris_ppo.py"
        ),
        docs="docs/studies/learning.md",
        figures=(
            Figure(
                _DEBRIS_CATCHABLE,
                _DEBRIS,
                "success_rate",
                thesis=80.0,
                unit="%",
                better="higher",
                tolerance=0.05,
                scale=100.0,
                departure="placements chosen where the Trunk's pull can catch (z 75-95 mm, 35"
                " and 40 mm cubes), the tests drawn like the training's; behaviour cloning of a"
                " planner's program first; one training seed",
                fmt="{:.2f}",
                docs="docs/studies/learning.md",
                protocol="the final policy (102 400 steps), no checkpoint chosen; 400 tests on"
                " placements from the planner's catch map drawn like the training's (seeds"
                " 30 000 on). Re-made on 2026-12-07 in one run from the clone, its policy kept:"
                " old figure 99.25 % (the first run, resumed from 30 720 steps, not kept)",
            ),
            Figure(
                _DEBRIS_OWN,
                _DEBRIS,
                "own_draw/success_rate",
                thesis=80.0,
                unit="%",
                better="higher",
                tolerance=0.05,
                scale=100.0,
                departure="the policy trained on the catchable placements, tested where the"
                " environment draws the cube (z 110-160 mm, 20-40 mm cubes), which holds no"
                " placement any program found catches",
                fmt="{:.2f}",
                docs="docs/studies/learning.md",
                protocol="the final policy above, 400 tests of the environment's own draw"
                " (seeds 30 000 on)",
            ),
            Figure(
                "PPO (1e5 steps), the environment's own draw, success",
                _DEBRIS_OWN_DRAW,
                "success_rate",
                thesis=80.0,
                unit="%",
                better="higher",
                tolerance=0.05,
                scale=100.0,
                departure="the environment's default draw (z 110-160 mm, 20-40 mm cubes) holds"
                " no placement any program found catches",
                fmt="{:.2f}",
                docs="docs/studies/learning.md",
                protocol="a PPO policy trained and tested on the environment's own draw, not"
                " the catchable policy above",
            ),
        ),
        not_kept="the PPO policy trained on the environment's own draw (the third figure) is not"
        " tracked (runs/ is ignored); re-made by `python experiments/rl/trunk_debris_ppo.py`"
        " (102 400 steps, 32 min, then 400 tests)",
        no_quick="its figure is 400 tests of a policy cloned from 40 planner episodes then"
        " trained by PPO: the tests alone take 17 min; the script writes into"
        " experiments/results/rl/ (no output option)",
        # The catchable policy is kept (policy.npz, 2.1 MB: the actor and the normaliser); its
        # 1 200 tests after training (catchable, the clone's, the own draw) took 4 310 s on the
        # shared machine; the re-evaluation runs 800 of those episodes: two thirds of it, 2 873 s
        # (estimated from that run, not timed alone).
        evaluate=Quick(
            "python experiments/rl/trunk_debris_ppo.py --evaluate"
            " experiments/results/rl/trunk_debris_ppo_catchable_course40_bc_1e5/policy.npz"
            " --tests 400 --own-draw-tests 400 --results {out}",
            {_DEBRIS: "summary.json"},
            seconds=2873.0,
            figures=(_DEBRIS_CATCHABLE, _DEBRIS_OWN),
        ),
    ),
    Study(
        name="cartstem-sac",
        thesis="§3.3.2",
        title="CartStemContact solved by SAC (MLP 3 x 512)",
        command="python experiments/rl/cartstem_sac.py --steps 200000 --stop-at 0.9",
        docs="docs/studies/learning.md",
        figures=(
            Figure(
                "steps to the policy that solves the task",
                _CARTSTEM,
                "100_goals/best_stochastic/step",
                thesis=2e5,
                unit="steps",
                better="lower",
                tolerance=0.5,
                departure="success within 1 mm (1 % of the 100 mm beam; the thesis 0.5 % of"
                " SofaGym's 30 cm); the run is partial, stopped at 40 160 steps (the session's"
                " budget): the policy is the best so far, not one that solved the task (84 %"
                " of the test goals sampled, 66 % with the mean action)",
                fmt="{:,.0f}",
                docs="docs/studies/learning.md",
                protocol="the policy of the best 20-goal evaluation (goals from seed 10 000 on,"
                " validation), reported on 100 test goals drawn from seed 20 000 on, which chose"
                " nothing; the run before (older environment, 40 000 steps) chose its policy on"
                " the 100 goals it reported: 100 % sampled, 85 % mean action",
            ),
            Figure(
                "that policy on 100 test goals, sampled actions, success",
                _CARTSTEM,
                "100_goals/best_stochastic/success_rate",
                thesis=None,
                unit="%",
                better="higher",
                tolerance=0.1,
                scale=100.0,
                fmt="{:.0f}",
                docs="docs/studies/learning.md",
                protocol="sampled after seeding torch with the test seed: the kept actor"
                " re-draws the same actions",
            ),
            Figure(
                "that policy on 100 test goals, mean actions, success",
                _CARTSTEM,
                "100_goals/best_deterministic/success_rate",
                thesis=None,
                unit="%",
                better="higher",
                tolerance=0.1,
                scale=100.0,
                fmt="{:.0f}",
                docs="docs/studies/learning.md",
            ),
        ),
        # The policy kept (the SAC actor alone, 2.0 MB); re-evaluated on 2026-12-08 (63 s, one
        # job beside): both success rates and returns to the last digit.
        evaluate=Quick(
            "python experiments/rl/cartstem_sac.py --evaluate"
            " experiments/results/rl/cartstem_sac/policy.npz --results {out}",
            {_CARTSTEM: "summary.json"},
            seconds=63.0,
            figures=(
                "that policy on 100 test goals, sampled actions, success",
                "that policy on 100 test goals, mean actions, success",
            ),
        ),
        not_kept="the step of the policy is the run's, not the policy's: re-made by the"
        " study's command (40 160 steps took 68 min of training)",
        no_quick="its figures are the best policy's 100-goal evaluations (400 episodes of up to"
        " 30 steps of 0.3 s) after SAC's 1000 warm-up steps: over 10 min; the script writes into"
        " experiments/results/rl/ (no output option)",
    ),
    Study(
        name="maze",
        thesis="§3.4.2, Fig. 3.15",
        title="The maze: OPD plans the tilts to each corner, the Tripod's inverse model replays"
        " them open loop",
        command=(
            "python experiments/planning/maze_corners.py --out out/maze/maze_corners.json && cp"
            " out/maze/maze_corners.json out/maze/maze_corners.png experiments/results/planning/"
        ),
        docs="docs/planning.md",
        figures=(
            Figure(
                "OPD on SimpleMaze, corners reached (within 5 mm)",
                _MAZE,
                "corners/*/simple_maze/reached",
                thesis=4.0,
                unit="of 4",
                better="higher",
                tolerance=0.01,
                scale=4.0,
                departure="budget 40 and gamma 0.9, which the thesis does not give",
                fmt="{:.0f}",
                docs="docs/planning.md",
            ),
            Figure(
                "the Tripod replaying the tilts open loop, corners reached (within 5 mm)",
                _MAZE,
                "corners/*/tripod/reached",
                thesis=None,
                unit="of 4",
                better="higher",
                tolerance=0.01,
                scale=4.0,
                departure="in simulation (the thesis replays on its physical Tripod); the"
                " inverse model linearised about rest from the FEM",
                fmt="{:.0f}",
                docs="docs/planning.md",
            ),
        ),
        quick=Quick(
            "python experiments/planning/maze_corners.py --budget 4 --steps 2"
            " --out {out}/maze_corners.json",
            {_MAZE: "maze_corners.json"},
            seconds=15.0,
        ),
    ),
    Study(
        name="table-4.1",
        thesis="Table 4.1",
        title="Real-time factor at dt = 0.01 s: FEM, reduced model and beam-skeleton proxy",
        command=(
            "python experiments/proxy/speed.py --out experiments/results/proxy_speed_nolag.json"
            " && python experiments/proxy/speed.py --reference"
            " --out experiments/results/proxy_speed_reference.json"
        ),
        docs="docs/studies/proxy-calibration.md",
        figures=(
            Figure(
                "Trunk FEM (and cube)",
                _SPEED,
                "real_time_factor/trunk_fem@0.01",
                thesis=0.22,
                unit="x real time",
                better="higher",
                tolerance=0.5,
                departure="Pliant's Trunk mesh (8 mm; the thesis' 900 nodes); " + _ENGINE,
                fmt="{:.1f}",
                docs="docs/studies/proxy-calibration.md",
            ),
            Figure(
                "Trunk proxy",
                _SPEED,
                "real_time_factor/trunk_proxy@0.01",
                thesis=0.62,
                unit="x real time",
                better="higher",
                tolerance=0.5,
                departure=_ENGINE,
                fmt="{:.1f}",
                docs="docs/studies/proxy-calibration.md",
            ),
            Figure(
                "Multigait FEM (SoftRobots' mesh, 15787 nodes)",
                _SPEED_REFERENCE,
                "real_time_factor/multigait_reference_fem@0.01",
                thesis=0.002,
                unit="x real time",
                better="higher",
                tolerance=0.5,
                departure="SoftRobots' Multigait mesh, 15787 nodes (the thesis' 34k); " + _ENGINE,
                fmt="{:.3f}",
                docs="docs/studies/proxy-calibration.md",
            ),
            Figure(
                "Multigait reduced model (31 modes)",
                _SPEED_REFERENCE,
                "real_time_factor/multigait_reference_reduced@0.01",
                thesis=0.06,
                unit="x real time",
                better="higher",
                tolerance=0.5,
                departure="Pliant's reduction of that mesh, 31 modes (SofaGym's: 63, hyper-reduced"
                " by its own selection); " + _ENGINE,
                fmt="{:.1f}",
                docs="docs/studies/proxy-calibration.md",
            ),
            Figure(
                "Multigait proxy",
                _SPEED_REFERENCE,
                "real_time_factor/multigait_proxy@0.01",
                thesis=0.57,
                unit="x real time",
                better="higher",
                tolerance=0.5,
                departure=_ENGINE,
                fmt="{:.1f}",
                docs="docs/studies/proxy-calibration.md",
            ),
            # the thesis' larger time steps, the same runs
            *(
                Figure(
                    f"{name}, dt = {dt} s",
                    file,
                    f"real_time_factor/{key}@{dt}",
                    thesis=thesis,
                    unit="x real time",
                    better="higher",
                    tolerance=0.5,
                    departure=_ENGINE,
                    fmt=fmt,
                    docs="docs/studies/proxy-calibration.md",
                )
                for dt, values in (
                    ("0.02", (0.49, 1.33, 0.004, 0.12, 1.06)),
                    ("0.03", (0.72, 1.96, 0.006, 0.17, 1.51)),
                )
                for (name, file, key, fmt), thesis in zip(
                    (
                        ("Trunk FEM (and cube)", _SPEED, "trunk_fem", "{:.1f}"),
                        ("Trunk proxy", _SPEED, "trunk_proxy", "{:.1f}"),
                        ("Multigait FEM", _SPEED_REFERENCE, "multigait_reference_fem", "{:.3f}"),
                        (
                            "Multigait reduced",
                            _SPEED_REFERENCE,
                            "multigait_reference_reduced",
                            "{:.1f}",
                        ),
                        ("Multigait proxy", _SPEED_REFERENCE, "multigait_proxy", "{:.1f}"),
                    ),
                    values,
                    strict=True,
                )
            ),
        ),
        quick=Quick(
            "python experiments/proxy/speed.py --steps 3 --cases trunk_fem trunk_proxy"
            " --out {out}/proxy_speed.json",
            {_SPEED: "proxy_speed.json"},
            seconds=22.0,
        ),
    ),
    Study(
        name="proxy-calibration",
        thesis="§4.1.3",
        title="Beam-skeleton proxies calibrated on the FEM: mean distance of matched points",
        command=(
            "pliant proxy calibrate multigait --out experiments/proxy/round1"
            " && pliant proxy calibrate trunk --out experiments/proxy"
        ),
        docs="docs/studies/proxy-calibration.md",
        figures=(
            Figure(
                "Multigait, optimisation positions",
                _MULTIGAIT_PROXY,
                "optimisation_error_mm",
                thesis=8.02,
                unit="mm",
                better="lower",
                tolerance=0.05,
                departure=_MULTIGAIT_FIT,
                fmt="{:.2f}",
                docs="docs/studies/proxy-calibration.md",
            ),
            Figure(
                "Multigait, validation positions",
                _MULTIGAIT_PROXY,
                "validation_error_mm",
                thesis=10.98,
                unit="mm",
                better="lower",
                tolerance=0.05,
                departure=_MULTIGAIT_FIT,
                fmt="{:.2f}",
                docs="docs/studies/proxy-calibration.md",
            ),
            Figure(
                "Trunk, optimisation positions",
                _TRUNK_PROXY,
                "optimisation_error_mm",
                thesis=10.2,
                unit="mm",
                better="lower",
                tolerance=0.05,
                departure=_TRUNK_FIT,
                fmt="{:.2f}",
                docs="docs/studies/proxy-calibration.md",
            ),
            Figure(
                "Trunk, validation positions",
                _TRUNK_PROXY,
                "validation_error_mm",
                thesis=9.85,
                unit="mm",
                better="lower",
                tolerance=0.05,
                departure=_TRUNK_FIT,
                fmt="{:.2f}",
                docs="docs/studies/proxy-calibration.md",
            ),
            Figure(
                "Trunk, actions it was not fitted on",
                _TRUNK_PROXY,
                "other_actions/error_mm",
                thesis=9.85,
                unit="mm",
                better="lower",
                tolerance=0.05,
                departure="the thesis validates on its own trajectory's intermediate positions",
                fmt="{:.2f}",
                docs="docs/studies/proxy-calibration.md",
            ),
        ),
        quick=Quick(
            "pliant proxy calibrate trunk --trials 2 --out {out}",
            {_TRUNK_PROXY: "trunk_calibration.json"},
            seconds=43.0,
        ),
    ),
    Study(
        name="proxy-transfer",
        thesis="§4.1.3",
        title="A policy learned on the Multigait proxy, transferred to the FEM by the inverse QP",
        command=(
            "pliant proxy transfer multigait --policy experiments/results/proxy/"
            "rl_multigait_surface --steps 8 --inverse-model twin --matched underside"
            " --angle-gain 0.5 --prior-weight 10 --out experiments/results/proxy/"
            "rl_multigait_surface/twin_underside_corrector_prior10"
            " && python experiments/proxy/prior_selection.py"
        ),
        docs="docs/studies/proxy-multigait.md",
        figures=(
            Figure(
                "relative difference of the walk, proxy against FEM",
                _TRANSFER,
                "relative_difference",
                thesis=5.0,
                unit="%",
                better="lower",
                tolerance=0.1,
                scale=100.0,
                departure="the prior's weight (10) is the best of five decided beforehand, but"
                " chosen on this very policy's transfer",
                fmt="{:.1f}",
                docs="docs/studies/proxy-multigait.md",
                protocol="weight 10 is the best of 0, 0.1, 1, 3, 10 and 30 on this policy's"
                " own transfer; chosen on the thesis' test sequence instead (validation) it is"
                " 3, and the policy held out transfers within the next figure's",
            ),
            Figure(
                "relative difference of the walk, the prior's weight chosen on the test"
                " sequence, the policy held out",
                _PRIOR_SELECTION,
                "held_out/relative_difference",
                thesis=5.0,
                unit="%",
                better="lower",
                tolerance=0.1,
                scale=100.0,
                departure="just over the thesis' 5 %: weight 3, the best on the test sequence"
                " (8.1 %), read from the committed transfers of prior.py",
                fmt="{:.1f}",
                docs="docs/studies/proxy-multigait.md",
                protocol="the weight chosen on the validation case (the thesis' test sequence),"
                " the learned policy's transfer reported: old 1.8 % (chosen on the policy)",
            ),
            Figure(
                "distance walked by the FEM",
                _TRANSFER,
                "fem_return",
                thesis=5.83,
                unit="mm",
                better="higher",
                tolerance=0.05,
                departure="Pliant's Multigait and proxy",
                fmt="{:.2f}",
                docs="docs/studies/proxy-multigait.md",
            ),
        ),
        quick=Quick(
            "pliant proxy transfer multigait --policy experiments/results/proxy/"
            "rl_multigait_surface --steps 1 --inverse-model twin --matched underside"
            " --angle-gain 0.5 --prior-weight 10 --out {out}",
            {_TRANSFER: "multigait_transfer.json"},
            seconds=177.0,
        ),
        # Measured 2026-12-07 at load 15-19 (the committed run took 135 s on a quieter one):
        # the re-evaluation gave the committed transfer to the last digit (FEM 10.1264 mm, 1.8 %).
        # The policy is kept as rl_multigait_surface/policy.npz since (pliant export-policy of its
        # model.zip: the same actions to the bit on 5 000 random and 60 environment observations;
        # a one-step run gave the committed first step, action 4, rewards within 1e-10).
        evaluate=Quick(
            "pliant proxy transfer multigait --policy experiments/results/proxy/"
            "rl_multigait_surface --steps 8 --inverse-model twin --matched underside"
            " --angle-gain 0.5 --prior-weight 10 --out {out}",
            {_TRANSFER: "multigait_transfer.json"},
            seconds=2090.0,
        ),
    ),
    Study(
        name="proxy-robustness",
        thesis="§4.1.3, Fig. 4.5, 4.6",
        title="Proxies with their parameters perturbed: PPO learns again on each, the policy"
        " transfers to the FEM",
        command=(
            "python experiments/proxy/robustness.py --levels 0,0.001,0.01,0.1 --parameters"
            " experiments/proxy/surface/multigait-joint_calibration.json --draws 3"
            " --feedforward 1 --transfer-steps 8 --tag _surface && python"
            " experiments/proxy/robustness.py --robot trunk --levels 0.1,0.01,0.001 --draws 5"
        ),
        docs="docs/studies/proxy-pipeline.md",
        figures=(
            *(
                Figure(
                    f"Multigait, parameters perturbed by {level}: FEM's travel in 8 transferred"
                    " steps, mean of 3 draws",
                    _ROBUST_MULTIGAIT,
                    f"rows/level={level}/transfer/fem_travel_mm",
                    thesis=None,
                    unit="mm",
                    better="higher",
                    tolerance=0.5,
                    departure="the thesis shows that the reward still increases at every level"
                    " (Fig. 4.5), without a number; 1440 PPO steps a draw",
                    fmt="{:.1f}",
                    docs="docs/studies/proxy-multigait.md",
                    protocol="every draw's final policy, none chosen",
                )
                for level in ("0.0", "0.001", "0.01", "0.1")
            ),
            *(
                Figure(
                    f"Trunk, parameters perturbed by {level}: FEM's mean final cube-goal"
                    " distance on 20 goals, mean of 5 draws (doing nothing: 21.3 mm)",
                    _ROBUST_TRUNK,
                    f"rows/level={level}/transfer/fem/mean_final_distance_mm",
                    thesis=None,
                    unit="mm",
                    better="lower",
                    tolerance=0.5,
                    departure="the thesis finds the Trunk's results the same as the Multigait's"
                    " (Fig. 4.6), without a number; 20 400 PPO steps a draw",
                    fmt="{:.1f}",
                    docs="docs/studies/proxy-pipeline.md",
                    protocol="every draw's final policy, none chosen",
                )
                for level in ("0.1", "0.01", "0.001")
            ),
        ),
        no_quick="each row is a PPO training on a perturbed proxy (3 to 10 min) and its"
        " transfer to the FEM; the script writes into experiments/results/proxy/ (no output"
        " option)",
        not_kept="the perturbed proxies' policies are not tracked (their folders hold"
        " Stable-Baselines3 models); the figures are re-made by the study's command (about 46"
        " min for the Multigait's 12 rows, 2.5 h for the Trunk's 15, on one core)",
    ),
    Study(
        name="graph-selector",
        thesis="§4.2.3",
        title="The configuration-space graph's Selector: accuracy on 50 000 held-out states",
        command=(
            "python experiments/graph/selector.py --train 100000 --epochs 60 --batch-size 128"
            " --schedule cosine"
        ),
        docs="docs/studies/graph.md",
        figures=(
            Figure(
                "Selector accuracy, CartStemContact partition",
                _SELECTOR,
                "test_accuracy",
                thesis=99.7,
                unit="%",
                better="higher",
                tolerance=0.005,
                scale=100.0,
                departure="the states drawn (obstacle positions and sizes randomised around the"
                " scene's), not the authors' 500 000 simulated environment steps; 100 000 of them"
                " for training, 20 % of those for validation",
                fmt="{:.2f}",
                docs="docs/studies/graph.md",
            ),
        ),
        quick=Quick(
            "python experiments/graph/selector.py --train 2000 --test 1000 --epochs 2 --out {out}",
            {_SELECTOR: "selector.json"},
            seconds=21.0,
        ),
        # The kept network was re-made by the study's command on 2026-12-07 (at load 20) and gave
        # the committed file's accuracies to the last digit; its re-evaluation took 28 s.
        evaluate=Quick(
            "python experiments/graph/selector.py --evaluate experiments/results/graph/selector.pt"
            " --out {out}",
            {_SELECTOR: "selector.json"},
            seconds=28.0,
        ),
    ),
    Study(
        name="graph-cartstem",
        thesis="§4.2.3",
        title="CartStemContact: steps to 80 % success, plain SAC against the graph method",
        command=(
            "python experiments/graph/cartstem.py --methods sac graph --seeds 0 1 2 --steps"
            " 20000 --eval-episodes 10 && python experiments/graph/cartstem.py --methods convex"
            " --seeds 0 1 2 --steps 8000 --eval-episodes 10"
        ),
        docs="docs/studies/graph.md",
        figures=(
            Figure(
                "plain SAC, mean of 3 seeds",
                _GRAPH,
                "runs/sac/*/iterations_to_solve",
                thesis=140000,
                unit="steps",
                better="lower",
                tolerance=0.3,
                departure="Pliant's CartStemContact (100 mm beam, 1 mm success), 10 goals an"
                " evaluation, 3 seeds",
                fmt="{:,.0f}",
                docs="docs/studies/graph.md",
            ),
            Figure(
                "graph, learned internal agents, mean of 3 seeds",
                _GRAPH,
                "runs/graph/*/iterations_to_solve",
                thesis=80000,
                unit="steps",
                better="lower",
                tolerance=0.3,
                departure="slower than plain SAC here (+88 %), where the thesis' is 42 % faster",
                fmt="{:,.0f}",
                docs="docs/studies/graph.md",
            ),
            Figure(
                "graph, the FEM inverse as internal agents, mean of 3 seeds",
                _GRAPH,
                "runs/convex/*/iterations_to_solve",
                thesis=40000,
                unit="steps",
                better="lower",
                tolerance=0.3,
                departure="the static FEM inverse as the convex internal agent",
                fmt="{:,.0f}",
                docs="docs/studies/graph.md",
            ),
        ),
        not_kept="the SAC and graph agents' checkpoints are not tracked (run folders are "
        "ignored); re-made by the study's command (3 seeds of 20 000 steps a method): the"
        " committed runs took 2.9 h in all (a seed: SAC 18 min, graph 29 min, convex 11 min)",
        no_quick="one seed of the graph method needs about 600 steps (0.08 s each) before its"
        " first evaluation and writes into experiments/results/graph/ by scene name; over 2 min",
    ),
    Study(
        name="table-5.1",
        thesis="Table 5.1",
        title="Learned condensed model, 6500 samples: standardised test loss",
        command=(
            "python experiments/condensed/table_5_1.py --workers 2 --work out/condensed_full"
            " && python experiments/condensed/table_5_1_corner.py --corner-samples 300"
            " --uniform-samples 6200 --epochs 1500"
            " && python experiments/condensed/table_5_1_protocol.py --workers 2"
            f" && cp out/condensed_full/finger_6500.pt {_TABLE_5_1_MODELS}/finger.pt"
        ),
        docs="docs/condensed.md",
        figures=(
            Figure(
                "Finger, under the protocol: held-out test",
                _TABLE_5_1,
                "finger/held_out/test_loss",
                thesis=3.79e-6,
                unit="",
                better="lower",
                tolerance=0.01,
                departure=_CONDENSED_SAMPLES,
                fmt="{:.2e}",
                docs="docs/condensed.md",
                protocol="the epoch chosen on the validation set (the 1625 samples earlier runs"
                " were tested on), tested on 1625 samples drawn afterwards (test stream of seed"
                " 1); old figure 4.78e-7 (chosen on its test set, the network not kept), new"
                " 4.16e-7",
            ),
            Figure(
                "Finger",
                _TABLE_5_1,
                "finger/test_loss",
                thesis=3.79e-6,
                unit="",
                better="lower",
                tolerance=0.5,
                departure=_CONDENSED_SAMPLES,
                fmt="{:.2e}",
                docs="docs/condensed.md",
                protocol="the epoch of least loss on this test split is reported (epoch 1480):"
                " the validation loss of the protocol's run, whose held-out test is the figure"
                " above; the run before (epoch 1475, network not kept) gave 4.78e-7",
            ),
            Figure(
                "Diamond, the corner where all cables pull 24-30 mm sampled",
                _TABLE_5_1_CORNER,
                "test_loss",
                thesis=6.52e-5,
                unit="",
                better="lower",
                tolerance=0.5,
                departure="the corner box was chosen after looking at the test losses;"
                " 6495 samples, 1500 epochs",
                fmt="{:.2e}",
                docs="docs/condensed.md",
                protocol="the box (all cables 24-30 mm) was declared after the uniform model's"
                " worst test sample, and the epoch is the one of least test loss: this is the"
                " validation loss of the protocol's run below (the same box, declared there by a"
                " rule on the validation set, and the same epoch 1471); on samples drawn"
                " afterwards the same network scores 2.49e-4",
            ),
            Figure(
                "Diamond, corner sampled, under the protocol: held-out test",
                _TABLE_5_1_PROTOCOL,
                "corner/test_loss",
                thesis=6.52e-5,
                unit="",
                better="lower",
                tolerance=0.01,
                departure="3.8 times the thesis' loss: 73 % of it from the worst of 1617"
                " held-out samples (median sample 2.4e-6); 6495 samples, 1500 epochs",
                fmt="{:.2e}",
                docs="docs/condensed.md",
                protocol="epoch and corner box chosen on the validation set (the 1622 samples"
                " the rows above were tested on; the box by a rule declared beforehand: 6 mm at"
                " the vertex nearest the worst validation sample), tested on 1617 samples drawn"
                " afterwards (test stream of seed 1); old figure 1.44e-5 (chosen on its test"
                " set), new 2.49e-4",
            ),
            Figure(
                "Diamond, uniform samples, under the protocol: held-out test",
                _TABLE_5_1_PROTOCOL,
                "uniform/test_loss",
                thesis=6.52e-5,
                unit="",
                better="lower",
                tolerance=0.01,
                departure="5.4 times the thesis' loss: 55 % of it from the worst of 1617"
                " held-out samples (median sample 4.8e-6); 3000 epochs",
                fmt="{:.2e}",
                docs="docs/condensed.md",
                protocol="epoch chosen on the validation set (the 1622 samples the rows above"
                " were tested on), tested on 1617 samples drawn afterwards; old figure 1.12e-4"
                " (chosen on its test set), new 3.55e-4",
            ),
            Figure(
                "Diamond, uniform samples",
                _TABLE_5_1,
                "diamond/test_loss",
                thesis=6.52e-5,
                unit="",
                better="lower",
                tolerance=0.5,
                departure="82 % of the loss from one test sample (all four cables at 28-29 mm);"
                " 3000 epochs",
                fmt="{:.2e}",
                docs="docs/condensed.md",
                protocol="the epoch of least test loss is reported (the training keeps the"
                " network at its best test epoch): the validation loss of the protocol's run"
                " (same epoch 2149); on samples drawn afterwards, 3.55e-4 (next figures)",
            ),
        ),
        quick=Quick(
            "python experiments/condensed/table_5_1.py --finger-samples 16 --diamond-samples 16"
            " --epochs 2 --work {out}/work --out {out}",
            {_TABLE_5_1: "table_5_1.json"},
            seconds=60.0,
        ),
        not_kept="the first Diamond runs' networks are not tracked (out/ is ignored; the"
        " study's command re-makes them: Diamond collection 16 min on two quiet cores, trainings"
        " 20-25 min a robot on one); the Finger's network and the protocol's two Diamond ones"
        " are kept (experiments/results/condensed/table_5_1_models, 1.7 MB each) and --evaluate"
        " scores them",
        # The protocol's networks, kept: the held-out samples solved again by the FEM from the
        # plan the models record (deterministic), then scored. On 2026-12-07 (a training and a
        # scene count beside it) it gave both committed Diamond test losses to the last digit,
        # and the Finger's (2 min, two trainings beside it) in session 49.
        evaluate=Quick(
            f"python experiments/condensed/table_5_1_protocol.py --evaluate {_TABLE_5_1_MODELS}"
            " --out {out} && python experiments/condensed/table_5_1.py --evaluate"
            f" {_TABLE_5_1_MODELS} --robot finger --out {{out}}",
            {
                _TABLE_5_1_PROTOCOL: "table_5_1_diamond_protocol.json",
                _TABLE_5_1: "table_5_1.json",
            },
            seconds=1188.0,
            figures=(
                "Finger, under the protocol: held-out test",
                "Diamond, corner sampled, under the protocol: held-out test",
                "Diamond, uniform samples, under the protocol: held-out test",
            ),
        ),
    ),
    Study(
        name="table-5.2",
        thesis="Table 5.2, Fig. 5.5",
        title="Finger on three meshes: test loss and the embedded loop's rate",
        command=(
            "python experiments/condensed/table_5_2.py --samples 1000 --epochs 1000"
            " --work out/condensed_t52 && cp out/condensed_t52/finger_coarse_1000.pt"
            f" {_MODELS}/"
        ),
        docs="docs/condensed.md",
        figures=(
            *(
                _table_5_2_loss(
                    f"test loss, {mesh} mesh, under the protocol: held-out test",
                    f"{key}/held_out/test_loss",
                    thesis,
                    "the epoch chosen on the plan's test split (its validation set), tested on"
                    " 250 samples drawn afterwards (the plan's test stream of seed 1); old"
                    f" figure {old} (chosen on its test set)",
                )
                for mesh, key, thesis, old in (
                    ("coarse", "coarse", 3.79e-6, "2.98e-6"),
                    ("fine", "fine", 4.26e-6, "2.28e-6"),
                    ("super-fine", "superfine", 3.60e-6, "3.20e-6"),
                )
            ),
            *(
                _table_5_2_loss(
                    f"test loss, {mesh} mesh",
                    f"{key}/test_loss",
                    thesis,
                    "the epoch of least loss on this test split is reported: a validation loss;"
                    " the held-out test is the figure above" + retrained,
                )
                for mesh, key, thesis, retrained in (
                    (
                        "coarse",
                        "coarse",
                        3.79e-6,
                        "; re-trained on 2026-12-07 to keep its network (the file's"
                        " `retrained`): the earlier run's network, not kept, gave 2.07e-6 at"
                        " epoch 991",
                    ),
                    (
                        "fine",
                        "fine",
                        4.26e-6,
                        "; re-trained in session 49 with its held-out test (the run before:"
                        " 2.28e-6)",
                    ),
                    (
                        "super-fine",
                        "superfine",
                        3.60e-6,
                        "; re-trained in session 49 with its held-out test (the run before:"
                        " 3.20e-6)",
                    ),
                )
            ),
            *(
                Figure(
                    f"network and QP loop, {mesh} mesh",
                    _TABLE_5_2,
                    f"{key}/loop_hz",
                    thesis=thesis,
                    unit="iterations/s",
                    better="higher",
                    tolerance=0.5,
                    departure="Algorithm 2 alone (the network in NumPy and a warm-started QP, one"
                    " thread, no simulation in the loop), where the thesis counts the frames of"
                    " its SOFA simulation using the model",
                    fmt="{:.0f}",
                    docs="docs/condensed.md",
                )
                for mesh, key, thesis in (
                    ("coarse", "coarse", 308.6),
                    ("fine", "fine", 334.4),
                    ("super-fine", "superfine", 296.7),
                )
            ),
        ),
        not_kept="the fine and super-fine meshes' networks (1.7 MB each) are not kept, for the"
        " repository's size (out/ is ignored); re-made by the study's command (their collection"
        " about 20 min on one quiet core)",
        quick=Quick(
            "python experiments/condensed/table_5_2.py --samples 8 --epochs 2"
            " --iterations 50 --work {out}/work --out {out}",
            {_TABLE_5_2: "table_5_2.json"},
            seconds=122.0,
        ),
        # The coarse mesh's network, kept: its test samples solved again by the FEM from the
        # plan the model records, its loss and its loop's rate measured again. On 2026-12-07
        # (nice 19, load 10-12) it gave the committed test loss to the last digit; the rate,
        # a timing of the machine, 1213/s: it meets its tolerance on a quiet machine only.
        evaluate=Quick(
            f"python experiments/condensed/table_5_2.py --evaluate {_MODELS} --resolutions"
            " coarse --samples 1000 --out {out}",
            {_TABLE_5_2: "table_5_2.json"},
            seconds=190.0,
            figures=(
                "test loss, coarse mesh",
                "test loss, coarse mesh, under the protocol: held-out test",
                "network and QP loop, coarse mesh",
            ),
        ),
    ),
    Study(
        name="table-5.3",
        thesis="§5.1.4, Table 5.3, Fig. 5.8, 5.9",
        title="The Finger with contact points, learned: a button pushed, a cube moved by three",
        command=(
            "python experiments/condensed/contacts.py --finger-samples 500 --gripper-poses 320"
            " --epochs 1000 --workers 2"
        ),
        docs="docs/condensed.md",
        figures=(
            *(
                Figure(
                    f"{robot}, under the protocol: held-out test",
                    _CONTACTS,
                    f"{key}_dataset/held_out/test_loss",
                    thesis=thesis,
                    unit="",
                    better="lower",
                    tolerance=0.5,
                    departure=departure,
                    fmt=fmt,
                    docs="docs/condensed.md",
                    protocol="the epoch chosen on the dataset's test split (its validation"
                    f" set), tested on {tested} drawn afterwards (the plan's test split under"
                    " seed 1); the next figure is the loss on the validation set",
                )
                for robot, key, thesis, departure, fmt, tested in (
                    (
                        "Finger with contact points",
                        "finger",
                        1.67e-6,
                        "500 samples in a box of cables and contact-point pushes about where the"
                        " cables put the points (the thesis samples the cube's space by inverse"
                        " control); " + _FEW_EPOCHS_CONTACTS,
                        "{:.2e}",
                        "125 samples",
                    ),
                    (
                        "three-finger gripper",
                        "gripper",
                        1.24e-3,
                        "320 cube poses by inverse control, 3 samples each; "
                        + _FEW_EPOCHS_CONTACTS,
                        "{:.1e}",
                        "240 samples of a chain of cube goals collected afresh",
                    ),
                )
            ),
            *(
                Figure(
                    robot,
                    _CONTACTS,
                    f"{key}_dataset/test_loss",
                    thesis=thesis,
                    unit="",
                    better="lower",
                    tolerance=0.5,
                    departure=_FEW_EPOCHS_CONTACTS,
                    fmt=fmt,
                    docs="docs/condensed.md",
                    protocol="the epoch of least loss on this test split is reported (the"
                    " thesis' protocol too): a validation loss; the held-out test is above",
                )
                for robot, key, thesis, fmt in (
                    ("Finger with contact points", "finger", 1.67e-6, "{:.2e}"),
                    ("three-finger gripper", "gripper", 1.24e-3, "{:.1e}"),
                )
            ),
            *(
                Figure(
                    f"button of 50 mN/mm, learned W: worst error of the push reached, {n}",
                    _CONTACTS,
                    f"button/learned_{steps}_steps/relative_error_max",
                    thesis=None,
                    unit="%",
                    better="lower",
                    tolerance=0.5,
                    scale=100.0,
                    fmt="{:.1f}",
                    docs="docs/condensed.md",
                )
                for steps, n in ((1, "one step"), (3, "three steps"))
            ),
            *(
                Figure(
                    f"cube on a 1.5 mm circle, {source} matrices: mean distance to the goals",
                    _CONTACTS,
                    f"gripper/{source}/distance_to_goal_mean_mm",
                    thesis=None,
                    unit="mm",
                    better="lower",
                    tolerance=0.5,
                    fmt="{:.2f}",
                    docs="docs/condensed.md",
                )
                for source in ("learned", "exact")
            ),
        ),
        quick=Quick(_CONTACTS_QUICK, {_CONTACTS: "contacts.json"}, seconds=34.0),
        # The two networks (256 x 3, 0.8 MB each), kept: the held-out samples solved again by
        # the FEM from the plans they record, the button and the circle driven again.
        evaluate=Quick(
            "python experiments/condensed/contacts.py --evaluate"
            " experiments/results/condensed/contacts/models --work {out}/work --out {out}",
            {_CONTACTS: "contacts.json"},
            seconds=_CONTACTS_EVALUATE_SECONDS,
            figures=(
                "Finger with contact points, under the protocol: held-out test",
                "three-finger gripper, under the protocol: held-out test",
                "button of 50 mN/mm, learned W: worst error of the push reached, one step",
                "button of 50 mN/mm, learned W: worst error of the push reached, three steps",
                "cube on a 1.5 mm circle, learned matrices: mean distance to the goals",
                "cube on a 1.5 mm circle, exact matrices: mean distance to the goals",
            ),
        ),
        not_kept="the validation losses (the epoch chosen on them) are the training's, not the"
        " networks': re-made by the study's command (every figure in about 6 minutes on two"
        " quiet cores)",
    ),
    Study(
        name="table-5.4",
        thesis="Table 5.4",
        title="Stiff-Flop, pressure actuation: standardised test loss",
        command=(
            "python experiments/condensed/stiff_flop.py --samples 40000 --epochs 200 --workers 2"
        ),
        docs="docs/condensed.md",
        figures=(
            Figure(
                "test loss",
                _TABLE_5_4,
                "test_loss",
                thesis=9.22e-4,
                unit="",
                better="lower",
                tolerance=0.5,
                departure="volume change 0-100 mm^3 (thesis 0-30), 40 000 samples, 200 epochs"
                " (thesis 50 000)",
                fmt="{:.2e}",
                docs="docs/condensed.md",
                protocol=_EPOCH_ON_TEST + "the study's command re-makes it (2 h)",
            ),
        ),
        not_kept="the network and dataset are not tracked (out/ is ignored); re-made by the "
        "study's command (the committed run: collection 115 min on 2 workers, training 10 min)."
        + _NETWORK_SIZE,
        no_quick="the Stiff-Flop's collection alone takes tens of minutes",
    ),
    Study(
        name="table-5.7",
        thesis="Table 5.7",
        title="Finger design parameters: test losses of G and F",
        command=(
            "python experiments/condensed/table_5_7.py --dataset mechanical --samples 10000"
            " --epochs 1000 --design-epochs 10000 --batch-size 256 --learning-rate 2e-3"
            " --activation silu --schedule cosine && python experiments/condensed/table_5_7.py"
            " --dataset geometric --samples 50000 --epochs 60 --design-epochs 60 --batch-size 256"
            " --learning-rate 2e-3 --activation silu --schedule cosine --workers 2"
        ),
        docs="docs/condensed.md",
        figures=(
            Figure(
                "mechanical parameters, G",
                _TABLE_5_7,
                "mechanical/g_test_loss",
                thesis=3.82e-7,
                unit="",
                better="lower",
                tolerance=0.5,
                departure=_MECHANICAL,
                fmt="{:.2e}",
                docs="docs/condensed.md",
                protocol=_EPOCH_ON_TEST + "the study's command re-makes it (80 min)",
            ),
            Figure(
                "mechanical parameters, F",
                _TABLE_5_7,
                "mechanical/f_test_loss",
                thesis=5.04e-5,
                unit="",
                better="lower",
                tolerance=0.5,
                departure=_MECHANICAL,
                fmt="{:.2e}",
                docs="docs/condensed.md",
                protocol=_EPOCH_ON_TEST + "the study's command re-makes it (80 min)",
            ),
            Figure(
                "geometry, G",
                _TABLE_5_7,
                "geometric/g_test_loss",
                thesis=0.19,
                unit="",
                better="lower",
                tolerance=0.5,
                departure="G stays flat from its first epoch (train and test alike)",
                fmt="{:.3g}",
                docs="docs/condensed.md",
                protocol=_EPOCH_ON_TEST + "the study's command re-makes it (about 2.5 h)",
            ),
            Figure(
                "geometry, F",
                _TABLE_5_7,
                "geometric/f_test_loss",
                thesis=0.13,
                unit="",
                better="lower",
                tolerance=0.5,
                departure="60 epochs (the thesis' best epoch 270), SiLU and a cosine learning rate",
                fmt="{:.3g}",
                docs="docs/condensed.md",
                protocol=_EPOCH_ON_TEST + "the study's command re-makes it (about 2.5 h)",
            ),
        ),
        not_kept="the networks and datasets are not tracked (out/ is ignored); re-made by the "
        "study's command (mechanical: collection 78 min on one core, F 7 min and G 4 min;"
        " geometric: 50 000 samples, about 2 h on 2 idle cores, then 2 networks of 14 min)."
        + _NETWORK_SIZE,
        no_quick="10 000 and 50 000 samples, each its own design and mesh: hours",
    ),
    Study(
        name="table-5.8",
        thesis="Table 5.8, Fig. 5.13",
        title="Trajectories, learned against exact condensed model; calibrating nu",
        command=(
            f"python experiments/condensed/trajectories.py {_MODELS}/finger_coarse_1000.pt"
            f" {_TABLE_5_1_MODELS}/diamond_protocol_uniform.pt && python"
            " experiments/condensed/calibration.py --samples 320 --samples-per-design 4"
            " --epochs 1500"
        ),
        docs="docs/condensed.md",
        figures=(
            Figure(
                "Finger closing, open loop, trajectory error",
                _TABLE_5_8,
                "finger_closing/open/table_5_8_error",
                thesis=1.0,
                unit="%",
                better="closer",
                tolerance=0.5,
                scale=100.0,
                departure="one design, the coarse Finger of table-5.2 (1000 samples, 1000 epochs),"
                " not the thesis' rows per design (0.29-1.03 % mechanical, 1.03-7.02 % geometric)",
                fmt="{:.1f}",
                docs="docs/condensed.md",
            ),
            Figure(
                "Diamond lifted circle, open loop, trajectory error",
                _TABLE_5_8,
                "diamond_lifted_circle/open/table_5_8_error",
                thesis=1.0,
                unit="%",
                better="closer",
                tolerance=0.5,
                scale=100.0,
                departure="the circle lifted to z = 140 mm, inside the learned box",
                fmt="{:.1f}",
                docs="docs/condensed.md",
            ),
            Figure(
                "nu calibrated from 0.45, 0.47 and 0.49 (truth 0.47), mean",
                _CALIBRATION,
                "runs/*/poisson_ratio",
                thesis=0.47,
                unit="",
                better="closer",
                tolerance=0.01,
                departure="Young's modulus not sampled (held at 3000 kPa, as Fig. 5.13 holds it):"
                " 320 samples over nu, 4 a design, 1500 epochs; cable 1 held at its length (the"
                " thesis' parametric finger has one cable)",
                fmt="{:.3f}",
                docs="docs/condensed.md",
            ),
        ),
        not_kept="the calibration's F and G are not tracked (out/ is ignored); re-made by the"
        " calibration's command." + _NETWORK_SIZE,
        retrain="python experiments/condensed/calibration.py --samples 320"
        " --samples-per-design 4 --epochs 1500",
        quick=Quick(
            "python experiments/condensed/table_5_1.py --finger-samples 16 --diamond-samples 16"
            " --epochs 2 --work {out}/work --out {out} && python experiments/condensed/"
            "trajectories.py {out}/work/finger_16.pt {out}/work/diamond_16.pt --iterations 1"
            " --out {out} && python experiments/condensed/calibration.py --samples 16 --epochs 3"
            " --iterations 5 --work {out}/work --out {out}",
            {_TABLE_5_8: "trajectories.json", _CALIBRATION: "calibration_finger.json"},
            seconds=140.0,
        ),
        # The Finger's network is table-5.2's coarse one, the Diamond's table-5.1's protocol
        # uniform one, both kept: their trajectories followed again (the committed rows were
        # made by this command on 2026-12-07, 59 s on the shared machine).
        evaluate=Quick(
            f"python experiments/condensed/trajectories.py {_MODELS}/finger_coarse_1000.pt"
            f" {_TABLE_5_1_MODELS}/diamond_protocol_uniform.pt --out {{out}}",
            {_TABLE_5_8: "trajectories.json"},
            seconds=59.0,
            figures=(
                "Finger closing, open loop, trajectory error",
                "Diamond lifted circle, open loop, trajectory error",
            ),
        ),
    ),
    Study(
        name="design",
        thesis="§5.1.6, Fig. 5.15-5.17",
        title="Designing the parametric Finger for dexterity and strength through its learned"
        " condensed model, checked on the FEM",
        command="python experiments/condensed/design.py --samples 640 --epochs 1500",
        docs="docs/condensed.md",
        figures=(
            *(
                Figure(
                    f"learned {what} against the FEM's, worst relative gap over the grid's and"
                    " the refined optima",
                    _DESIGN,
                    f"fem_check_gap/{key}_max_relative",
                    thesis=None,
                    unit="%",
                    better="lower",
                    tolerance=0.5,
                    scale=100.0,
                    departure=_DESIGN_DATA,
                    fmt="{:.1f}",
                    docs="docs/condensed.md",
                )
                for what, key in (
                    ("bending angle (dexterity, Eq. 5.17)", "angle_rad"),
                    ("tip force (strength, Eq. 5.19)", "tip_force_mN"),
                )
            ),
            Figure(
                "the strongest design, refined: its length",
                _DESIGN,
                "refined/strength/design/length",
                thesis=42.0,
                unit="mm",
                better="closer",
                tolerance=0.05,
                departure="the shortest length of the box, where the thesis finds the longest:"
                " Pliant's finger, its cables 0.4 of the height from the mid-plane, pushes"
                " harder the stiffer and shorter it is; height and joint height at their"
                " maxima, as the thesis'. " + _DESIGN_DATA,
                fmt="{:.1f}",
            ),
        ),
        quick=Quick(
            "python experiments/condensed/design.py --samples 16 --samples-per-design 8"
            " --epochs 2 --iterations 2 --work {out}/work --out {out}",
            {_DESIGN: "design/design.json"},
            seconds=46.0,
        ),
        # The parametric model (F 3 x 450 and G 2 x 64, 1.7 MB), kept: every figure is of the
        # model alone (the study on it, then the FEM at the designs it finds).
        evaluate=Quick(
            "python experiments/condensed/design.py --evaluate"
            " experiments/results/condensed/design/model.pt --out {out}",
            {_DESIGN: "design/design.json"},
            seconds=_DESIGN_EVALUATE_SECONDS,
        ),
    ),
    Study(
        name="trajopt-diamond",
        thesis="§5.2.3",
        title="Diamond DDP on the condensed dynamics: iterations to converge",
        command="python experiments/trajopt/diamond.py",
        docs="docs/trajopt.md",
        figures=(
            Figure(
                "linear part, iterations",
                _TRAJOPT,
                "runs/run=linear/iterations",
                thesis=208,
                unit="iterations",
                better="lower",
                tolerance=0.1,
                departure="Pliant's Diamond (mesh 20 mm), its own goals and weights",
                fmt="{:.0f}",
                docs="docs/trajopt.md",
            ),
            Figure(
                "non-linear part (the thesis' lift), iterations before it stalls",
                _TRAJOPT,
                "runs/run=non-linear/iterations",
                thesis=1000,
                unit="iterations",
                better="lower",
                tolerance=0.1,
                departure="stalls (no cost decrease) where the thesis runs to its cap",
                fmt="{:.0f}",
                docs="docs/trajopt.md",
            ),
        ),
        quick=Quick(
            "python experiments/trajopt/diamond.py --max-iterations 1 --out {out}",
            {_TRAJOPT: "diamond.json"},
            seconds=144.0,
        ),
    ),
    Study(
        name="trajopt-stiff-flop-lianford",
        thesis="§5.2.4, §5.2.5, Fig. 5.21, 5.22",
        title="DDP on the condensed dynamics: the Stiff-Flop and the Lianford reach their goals",
        command=" && ".join(
            f"pliant trajopt {name} --out experiments/results/trajopt" for name in _SCENARIOS
        ),
        docs="docs/trajopt.md",
        figures=tuple(
            Figure(
                f"{run}, error at the end of the horizon",
                f"experiments/results/trajopt/{scenario}.json",
                f"runs/run={run}/final_error",
                thesis=None,
                unit="mm",
                better="lower",
                tolerance=0.1,
                departure="Pliant's Stiff-Flop and Lianford, their goals reachable by"
                " construction (where a constant actuation rests the effector); the thesis"
                " plots its trajectories without a number",
                fmt="{:.3f}",
                docs="docs/trajopt.md",
            )
            for scenario, run in (
                ("stiff-flop", "stiff-flop-middle"),
                ("stiff-flop", "stiff-flop-tip"),
                ("lianford-spiral", "lianford-spiral"),
                ("lianford-pick-place", "lianford-pick-place"),
                ("lianford-orientation", "lianford-orientation"),
            )
        ),
        quick=Quick(
            " && ".join(f"pliant trajopt {name} --quick --out {{out}}" for name in _SCENARIOS),
            {f"experiments/results/trajopt/{name}.json": f"{name}.json" for name in _SCENARIOS},
            seconds=77.0,
        ),
    ),
    Study(
        name="diff-routing",
        thesis="issue 63 (beyond the thesis)",
        title="Finger cable routing: L-BFGS-B on the exact gradient against Nelder-Mead and TPE",
        command="python experiments/diff/routing.py",
        docs="docs/diff.md",
        figures=tuple(
            Figure(
                f"{method}, fingertip drop for 8 mm of cable",
                _ROUTING,
                f"methods/{method}/reach_mm",
                thesis=None,
                unit="mm",
                better="higher",
                tolerance=0.02,
                fmt="{:.2f}",
                docs="docs/diff.md",
            )
            for method in ("L-BFGS-B + adjoint", "Nelder-Mead", "Optuna TPE")
        )
        + (
            Figure(
                "the Finger's own routing, fingertip drop",
                _ROUTING,
                "initial_reach_mm",
                thesis=None,
                unit="mm",
                better="higher",
                tolerance=0.001,
                fmt="{:.2f}",
                docs="docs/diff.md",
            ),
        ),
        quick=Quick(
            "python experiments/diff/routing.py --lbfgs 8 --budget 8 --out {out}/routing.json",
            {_ROUTING: "routing.json"},
            seconds=34.0,
        ),
    ),
    Study(
        name="diff-control",
        thesis="§5.2.3 by gradient (issue 63)",
        title="Open-loop control by L-BFGS-B on the exact rollout gradient against box-DDP",
        command="python experiments/diff/control.py && python experiments/diff/control.py"
        " --task trunk",
        docs="docs/diff.md",
        figures=(
            Figure(
                "Diamond: L-BFGS-B + adjoint, final cost (full FEM)",
                _DIFF_CONTROL["Diamond"],
                f"{_LBFGS}/cost_full_fem",
                thesis=None,
                unit="",
                better="lower",
                tolerance=0.02,
                fmt="{:.2f}",
                docs="docs/diff.md",
            ),
            Figure(
                "Diamond: L-BFGS-B + adjoint, wall time",
                _DIFF_CONTROL["Diamond"],
                f"{_LBFGS}/wall_time_s",
                thesis=None,
                unit="s",
                better="lower",
                tolerance=0.5,
                departure=_LOADED,
                fmt="{:.1f}",
                docs="docs/diff.md",
            ),
            Figure(
                "Diamond: box-DDP, no change bound, final cost (full FEM)",
                _DIFF_CONTROL["Diamond"],
                f"{_DDP}/cost_full_fem",
                thesis=None,
                unit="",
                better="lower",
                tolerance=0.02,
                fmt="{:.2f}",
                docs="docs/diff.md",
            ),
            Figure(
                "Diamond: box-DDP, no change bound, wall time",
                _DIFF_CONTROL["Diamond"],
                f"{_DDP}/wall_time_s",
                thesis=None,
                unit="s",
                better="lower",
                tolerance=0.5,
                departure=_LOADED,
                fmt="{:.1f}",
                docs="docs/diff.md",
            ),
            Figure(
                "Trunk: L-BFGS-B + adjoint, final cost (full FEM)",
                _DIFF_CONTROL["Trunk"],
                f"{_LBFGS}/cost_full_fem",
                thesis=None,
                unit="",
                better="lower",
                tolerance=0.02,
                fmt="{:.2f}",
                docs="docs/diff.md",
            ),
            Figure(
                "Trunk: L-BFGS-B + adjoint, wall time",
                _DIFF_CONTROL["Trunk"],
                f"{_LBFGS}/wall_time_s",
                thesis=None,
                unit="s",
                better="lower",
                tolerance=0.5,
                departure=_LOADED,
                fmt="{:.1f}",
                docs="docs/diff.md",
            ),
            Figure(
                "Trunk: box-DDP, no change bound, final cost (full FEM)",
                _DIFF_CONTROL["Trunk"],
                f"{_DDP}/cost_full_fem",
                thesis=None,
                unit="",
                better="lower",
                tolerance=0.02,
                fmt="{:.2f}",
                docs="docs/diff.md",
            ),
            Figure(
                "Trunk: box-DDP, no change bound, wall time",
                _DIFF_CONTROL["Trunk"],
                f"{_DDP}/wall_time_s",
                thesis=None,
                unit="s",
                better="lower",
                tolerance=0.5,
                departure=_LOADED,
                fmt="{:.1f}",
                docs="docs/diff.md",
            ),
        ),
        quick=Quick(
            "python experiments/diff/control.py --quick --out {out}/control.json && python"
            " experiments/diff/control.py --task trunk --quick --out {out}/control_trunk.json",
            {
                _DIFF_CONTROL["Diamond"]: "control.json",
                _DIFF_CONTROL["Trunk"]: "control_trunk.json",
            },
            seconds=221.0,
        ),
    ),
    Study(
        name="diff-policy",
        thesis="§3.1.2 by gradient (issue 63)",
        title="Diamond reaching: analytic policy gradients against PPO, in environment steps",
        command="python experiments/diff/policy.py",
        docs="docs/studies/diff-policy.md",
        figures=tuple(
            Figure(
                f"{label}, {what} on 10 held-out goals",
                _DIFF_POLICY,
                f"{name}/test/{key}",
                thesis=None,
                unit=unit,
                scale=scale,
                better=better,
                tolerance=1.0 if key == "success_rate" else 0.5,
                departure=_REACHABLE,
                fmt=fmt,
                docs="docs/studies/diff-policy.md",
                protocol="the policy of the evaluation with the best success on 5 validation goals;"
                " the 10 test goals drawn after training, from their own seed",
            )
            for name, label in (("apg", "analytic policy gradient"), ("ppo", "PPO"))
            for what, key, unit, scale, better, fmt in (
                ("success", "success_rate", "%", 100.0, "higher", "{:.0f}"),
                ("mean final distance", "final_distance_mm", "mm", 1.0, "lower", "{:.1f}"),
            )
        )
        + (
            Figure(
                "validation success both learners reached",
                _DIFF_POLICY,
                "same_success/level",
                thesis=None,
                unit="%",
                scale=100.0,
                better="higher",
                tolerance=1.0,
                departure=_REACHABLE,
                fmt="{:.0f}",
                docs="docs/studies/diff-policy.md",
            ),
        ),
        not_kept="the validation curves' checkpoints are in out/diff/policy/ (ignored), so the"
        " steps to the same success are re-made by the study's command (12 min on the shared"
        " 2-core machine, both learners side by side)",
        quick=Quick(
            "python experiments/diff/policy.py --quick --out {out}/policy.json",
            {_DIFF_POLICY: "policy.json"},
            seconds=276.0,
        ),
        # The two selected policies are kept (experiments/results/diff/policy_models, 211 kB);
        # re-evaluated on 2026-12-07 they gave the committed held-out figures to the last digit.
        evaluate=Quick(
            "python experiments/diff/policy.py --evaluate experiments/results/diff/policy_models"
            " --out {out}/policy.json",
            {_DIFF_POLICY: "policy.json"},
            seconds=60.0,
            figures=tuple(
                f"{label}, {what} on 10 held-out goals"
                for label in ("analytic policy gradient", "PPO")
                for what in ("success", "mean final distance")
            ),
        ),
    ),
)


def study(name: str) -> Study:
    """The study called ``name``."""
    for entry in STUDIES:
        if entry.name == name:
            return entry
    raise KeyError(f"no study {name!r}; studies: {', '.join(s.name for s in STUDIES)}")
