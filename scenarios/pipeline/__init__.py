"""The one assembly of world, sensors, matchers and estimators, fed in time order (runs, replays, closed loop, gym, exports)."""
