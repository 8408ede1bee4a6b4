"""bench-images' rows for a real camera's large frames: each encoding read and tracked (the
figures are the command's to print, not a test's to time)."""

from omni_micro_cli.commands.bench_images import DRIVER_ENCODINGS, driver_frame_costs


def test_a_real_cameras_large_frames_are_read_and_tracked_in_each_encoding(capsys):
    rows = driver_frame_costs(1)
    assert [row['encoding'] for row in rows] == list(DRIVER_ENCODINGS)
    for row in rows:
        assert row['resolution'] == [2448, 2048]
        assert float(row['per_frame_ms']) > 0 and float(row['of_frame_period']) > 0  # type: ignore[arg-type]
    printed = capsys.readouterr().out
    assert '2448 x 2048 bayer_rggb8  read and track' in printed
    assert 'of the 30 Hz period' in printed
