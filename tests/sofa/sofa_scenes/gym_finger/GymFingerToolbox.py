"""The toolbox of gym_finger (written for the tests, in the form SofaGym gives its
environments' toolboxes): the reward, the goal and the action as Sofa.Core.Controllers that
the scene adds to its root, the command started as an SPLIB animation (``startCmd``), and
the functions the environment calls (``getState``, ``getReward``)."""

import numpy as np
import Sofa.Core
from splib3.animation.animate import Animation

PULL = {0: 5.0, 1: -5.0}  # mm of cable per action: pull, release


def tip_position(root):
    return np.array(root.finger.Effector.tipMO.position.value[0])


class rewardShaper(Sofa.Core.Controller):
    """The reward: the share of the distance to the goal closed since the last call."""

    def __init__(self, *args, **kwargs):
        Sofa.Core.Controller.__init__(self, *args, **kwargs)
        self.rootNode = kwargs["rootNode"]
        self.goal_pos = np.array(kwargs["goalPos"], dtype=float)
        self.prev_dist = None

    def update(self, goal=None):
        if goal is not None:
            self.goal_pos = np.array(goal, dtype=float)
        self.prev_dist = float(np.linalg.norm(tip_position(self.rootNode) - self.goal_pos))

    def getReward(self):
        dist = float(np.linalg.norm(tip_position(self.rootNode) - self.goal_pos))
        reward = (self.prev_dist - dist) / self.prev_dist
        self.prev_dist = dist
        return reward, dist


class goalSetter(Sofa.Core.Controller):
    """Places the goal's MechanicalObject, which the effector's goal links to."""

    def __init__(self, *args, **kwargs):
        Sofa.Core.Controller.__init__(self, *args, **kwargs)
        self.goalMO = kwargs["goalMO"]
        self.goalPos = kwargs["goalPos"]

    def update(self, goal=None):
        self.goalPos = self.goalPos if goal is None else goal
        with self.goalMO.position.writeable() as position:
            position[0] = self.goalPos


class applyAction(Sofa.Core.Controller):
    """Sets the cable's displacement; `start` is where the current command began."""

    def __init__(self, *args, **kwargs):
        Sofa.Core.Controller.__init__(self, *args, **kwargs)
        self.cable = kwargs["root"].finger.cable.cable
        self.start = 0.0
        self.commands = []

    def begin(self):
        self.start = float(self.cable.value[0])

    def apply_action(self, displacement):
        self.cable.value = [self.start + displacement]

    def onAnimateEndEvent(self, event):
        self.commands.append(float(self.cable.value[0]))


def startCmd(root, action, duration):
    """Ramps the cable by the action's pull over `duration` seconds of simulated time."""
    root.applyAction.begin()

    def executeAnimation(root, pull, factor):
        root.applyAction.apply_action(factor * pull)

    root.AnimationManager.addAnimation(
        Animation(
            onUpdate=executeAnimation,
            params={"root": root, "pull": PULL[action]},
            duration=duration,
            mode="once",
            realTimeClock=False,
        )
    )


def getState(root):
    return [*tip_position(root), *np.array(root.Goal.GoalMO.position.value[0])]


def getReward(root):
    """Whether the tip is within 1 mm of the goal, and the reward."""
    reward, distance = root.Reward.getReward()
    return distance < 1.0, reward
