"""Tutorial: the configuration-space graph (thesis §4.2) on its toy. A point on a segment split
into three regions (left, middle, right: the shape of CartStemContact's contact graph) must
reach a goal in the right region from the left one. The graph agent (Selector or partition,
Evaluator, an external agent per region to move to a neighbour, an internal agent per region to
solve the task there) learns beside plain SAC; with closed-form controllers as the internal
agents ("convex"), only the Evaluator and the external agents learn."""

from _common import QUICK, save_figure

from pliant.learn.graph import FlatSAC, GraphAgent, GraphConfig
from pliant.learn.graph.toy import CorridorEnv, corridor_controller, corridor_graph
from pliant.viz.render import offscreen_figure

graph = corridor_graph()  # nodes left, middle, right; each linked to its neighbours
print("path from left to right:", [graph.names[i] for i in graph.path(0, 2)])

steps, every = (300, 150) if QUICK else (2000, 250)
config = GraphConfig(hidden=64 if QUICK else 256, learning_starts=100 if QUICK else 500)
env = CorridorEnv()
learners = {
    "plain SAC": FlatSAC(env.observation_space, env.action_space, config, seed=0),
    "graph": GraphAgent(graph, env.observation_space, env.action_space, config, seed=0),
    "graph + convex": GraphAgent(
        graph,
        env.observation_space,
        env.action_space,
        config,
        controllers=dict.fromkeys(range(3), corridor_controller()),
        seed=0,
    ),
}
fig = offscreen_figure(6.5, 3.8)
ax = fig.add_subplot(1, 1, 1)
for name, learner in learners.items():
    history = learner.learn(CorridorEnv(), steps, eval_every=every, eval_episodes=5)
    ax.plot([h["steps"] for h in history], [h["success"] for h in history], "o-", label=name)
    print(f"{name}: success {[h['success'] for h in history]} at {[h['steps'] for h in history]}")
ax.set_xlabel("environment steps")
ax.set_ylabel("success rate (5 evaluation episodes)")
ax.set_ylim(-0.05, 1.05)
ax.set_title("Corridor: reach the goal two regions away")
ax.legend()
ax.grid(alpha=0.3)
save_figure(fig, "graph_corridor.png")
