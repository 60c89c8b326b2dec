"""The load run's synthetic recording (``python -m station.bench load``): a long, plausible
drive whose bands see the obstacles, with a few frames damaged on the line."""

from station.bench import long_recording
from station.cli import make_station
from station.session import StationRun


def test_long_recording_is_a_plausible_drive_that_sees_obstacles():
    data = long_recording(minutes=0.5, seed=1)
    assert long_recording(minutes=0.5, seed=1) == data
    st = make_station((6.0, 0.0), (-1.0, -2.5, 7.5, 2.5))
    st.replan = lambda t, reason: None          # the map and the link only: no planning
    run = StationRun(st)
    infos = run.feed(data)
    run.finish()
    link = st.link_stats()
    assert 0 < link["rejected_total"] < 0.1 * 300 and link["lost"] == link["rejected_total"]
    assert link["accepted"] + link["lost"] == 300 and link["implausible"] == 0
    assert sum(1 for i in infos if i.points) > 100
    assert st.grid.occupied().sum() > 20
    x = [i.pose[0] for i in infos]
    assert min(x) < 1.0 and max(x) > 3.0
