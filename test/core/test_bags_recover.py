"""Recovery after a SIGKILLed writer, a cut chunk, a corrupt chunk and a lost metadata.yaml."""
import os
import signal
import subprocess
import sys
import textwrap

import pytest
import yaml

from rollability_ros.core.bags.metadata import BagError, read_metadata
from rollability_ros.core.bags.reader import BagReader, bag_info
from rollability_ros.core.bags.recover import recover
from test_bags import installed_hash, string_cdr, write_string_bag

#: The writer subprocess: flushed messages are acknowledged on stdout, then more are written and never flushed.
WRITER_SCRIPT = textwrap.dedent("""
    import sys, time
    from rollability_ros.core.bags.writer import BagWriter
    from test_bags import T0_NS, string_cdr
    writer = BagWriter(sys.argv[1], custom_data={"operator": "kill test"}, split_max_bytes=4000,
                       chunk_size_bytes=1 << 20, flush_interval_s=3600)
    writer.add_topic("/a", "std_msgs/msg/String", offered_qos_profiles=[{"durability": "transient_local"}])
    writer.add_topic("/quiet", "geometry_msgs/msg/PoseStamped")
    for index in range(400):
        writer.write("/a", string_cdr(f"message {index}"), T0_NS + index)
        if index % 7 == 6:
            writer.flush()
    writer.flush()
    print("acknowledged 400", flush=True)
    for index in range(400, 450):
        writer.write("/a", string_cdr(f"message {index}"), T0_NS + index)
    print("unflushed 50", flush=True)
    time.sleep(60)
""")


def test_sigkill_of_writer_loses_only_the_open_chunk_and_keeps_all_metadata(tmp_path):
    bag = _killed_writer_bag(tmp_path)

    report = recover(bag)
    statuses = [f["status"] for f in report["files"]]
    assert len(statuses) > 2 and statuses[:-1] == ["intact"] * (len(statuses) - 1) and statuses[-1] == "recovered"
    assert report["message_count"] == 400 and report["topics"] == {"/a": 400, "/quiet": 0}
    assert [m.data for m in BagReader(bag)] == [string_cdr(f"message {i}") for i in range(400)]

    information = read_metadata(bag)
    assert information["custom_data"] == {"operator": "kill test"} and information["ros_distro"] == "jazzy"
    assert information["storage_identifier"] == "mcap" and information["version"] == 9
    topics = {t["topic_metadata"]["name"]: t for t in information["topics_with_message_count"]}
    assert topics["/a"]["topic_metadata"]["offered_qos_profiles"][0]["durability"] == "transient_local"
    assert topics["/quiet"]["topic_metadata"]["type_description_hash"] == installed_hash(
        "geometry_msgs/msg/PoseStamped")
    assert sum(f["message_count"] for f in information["files"]) == 400
    assert not os.path.exists(bag / ".recovery.json")
    info = bag_info(bag)
    assert info["warnings"] == [] and {t["name"] for t in info["topics"]} == {"/a", "/quiet"}


def _chunk_indexes(path):
    from mcap.reader import make_reader

    with open(path, "rb") as stream:
        return make_reader(stream).get_summary().chunk_indexes


def test_cut_inside_a_chunk_keeps_the_complete_chunks(tmp_path):
    bag = tmp_path / "cut"
    written = write_string_bag(bag, 300, chunk_size_bytes=2048)
    path = bag / "cut_0.mcap"
    chunks = _chunk_indexes(path)
    assert len(chunks) > 3
    cut = chunks[2].chunk_start_offset + chunks[2].chunk_length // 2
    path.write_bytes(path.read_bytes()[:cut])
    report = recover(bag)
    (entry,) = report["files"]
    assert entry["status"] == "recovered" and entry["chunks_recovered"] == 2 and entry["bytes_discarded"] > 0
    recovered = list(BagReader(bag))
    assert recovered == written[:len(recovered)] and len(recovered) == report["message_count"] > 0
    assert read_metadata(bag)["custom_data"] == {"campaign": "test"}


def test_corrupt_chunk_is_skipped_and_later_chunks_kept(tmp_path):
    bag = tmp_path / "corrupt"
    written = write_string_bag(bag, 300, chunk_size_bytes=2048)
    path = bag / "corrupt_0.mcap"
    chunks = _chunk_indexes(path)
    data = bytearray(path.read_bytes()[:chunks[-1].chunk_start_offset])   # also drop the last chunk + summary
    middle = chunks[1].chunk_start_offset + chunks[1].chunk_length - 20
    data[middle] ^= 0xFF
    path.write_bytes(bytes(data))
    report = recover(bag)
    (entry,) = report["files"]
    assert entry["chunks_discarded"] == 1 and entry["chunks_recovered"] == len(chunks) - 2
    recovered = list(BagReader(bag))
    assert set(recovered) < set(written) and written[0] in recovered and len(recovered) == report["message_count"]


def test_recover_without_metadata_yaml_takes_fields_from_the_storage_files(tmp_path):
    bag = tmp_path / "nometa"
    written = write_string_bag(bag, 200, split_max_duration_s=0.5)
    last = sorted(bag.glob("*.mcap"))[-1]
    last.write_bytes(last.read_bytes()[:-200])
    (bag / "metadata.yaml").unlink()
    recover(bag)
    information = read_metadata(bag)
    assert information["custom_data"] == {"campaign": "test"} and information["ros_distro"] == "jazzy"
    topic = information["topics_with_message_count"][0]["topic_metadata"]
    assert topic["type_description_hash"] == installed_hash("std_msgs/msg/String")
    assert topic["offered_qos_profiles"][0]["depth"] == 5
    assert list(BagReader(bag))[:150] == written[:150]


def test_recover_leaves_a_clean_bag_unchanged(tmp_path):
    bag = tmp_path / "clean"
    write_string_bag(bag, 100, split_max_duration_s=0.3)
    before = {p.name: p.read_bytes() for p in bag.glob("*.mcap")}
    metadata_before = yaml.safe_load((bag / "metadata.yaml").read_text())
    report = recover(bag)
    assert {f["status"] for f in report["files"]} == {"intact"}
    assert {p.name: p.read_bytes() for p in bag.glob("*.mcap")} == before
    assert yaml.safe_load((bag / "metadata.yaml").read_text()) == metadata_before


def test_recover_empty_storage_file_left_by_a_kill_right_after_a_split(tmp_path):
    bag = tmp_path / "empty"
    written = write_string_bag(bag, 20)
    (bag / "empty_1.mcap").write_bytes(b"")
    report = recover(bag)
    assert [f["status"] for f in report["files"]] == ["intact", "recovered"]
    assert list(BagReader(bag)) == written
    assert read_metadata(bag)["relative_file_paths"] == ["empty_0.mcap", "empty_1.mcap"]


def test_committed_bag_of_a_killed_writer_recovers(tmp_path):
    """test/resources/killed_bag: a writer SIGKILLed with 60 messages flushed and 10 in its open chunk."""
    import shutil

    bag = tmp_path / "killed_bag"
    shutil.copytree(os.path.join(os.path.dirname(__file__), "..", "resources", "killed_bag"), bag)
    report = recover(bag)
    assert [f["status"] for f in report["files"]] == ["intact", "recovered"]
    assert report["topics"] == {"/a": 60, "/quiet": 0}
    assert [m.data for m in BagReader(bag)] == [string_cdr(f"message {i}") for i in range(60)]
    information = read_metadata(bag)
    assert information["custom_data"] == {"fixture": "killed by SIGKILL"}
    assert information["topics_with_message_count"][0]["topic_metadata"]["offered_qos_profiles"][0][
        "durability"] == "transient_local"


# --- issue 17: recover never makes a bag worse ---------------------------------------------------------------
SAMPLE_BAG = os.path.join(os.path.dirname(__file__), "..", "..", "bags", "sample")


def _sample_copy(tmp_path):
    import shutil

    bag = tmp_path / "sample"
    shutil.copytree(SAMPLE_BAG, bag)
    return bag, bag / "bag_0.mcap"


def _flip(path, offsets):
    data = bytearray(path.read_bytes())
    for offset in offsets:
        data[offset] ^= 0xFF
    path.write_bytes(bytes(data))


def test_flipped_header_bytes_keep_every_intact_chunk(tmp_path):
    """Bytes 3 and 20 of the sample flipped (magic and header): every message survives, the original is kept."""
    bag, path = _sample_copy(tmp_path)
    expected = [(m.topic, m.data, m.log_time_ns) for m in BagReader(SAMPLE_BAG)]
    _flip(path, [3, 20])
    damaged = path.read_bytes()
    report = recover(bag)
    (entry,) = report["files"]
    assert entry["status"] == "recovered" and entry["chunks_discarded"] == 0
    assert report["message_count"] == len(expected) == 2362
    assert [(m.topic, m.data, m.log_time_ns) for m in BagReader(bag)] == expected
    assert (bag / ("bag_0.mcap" + ".before-recover")).read_bytes() == damaged


def test_bytes_flipped_inside_a_chunk_are_found_and_only_that_chunk_is_lost(tmp_path):
    """64 bytes flipped inside a chunk: not "intact"; the chunk is dropped, every other chunk is kept."""
    bag, path = _sample_copy(tmp_path)
    chunks = _chunk_indexes(path)
    assert len(chunks) > 2
    middle = chunks[1].chunk_start_offset + chunks[1].chunk_length // 2
    _flip(path, range(middle, middle + 64))
    report = recover(bag)
    (entry,) = report["files"]
    assert entry["status"] == "recovered" and entry["chunks_discarded"] == 1
    assert entry["chunks_recovered"] == len(chunks) - 1
    recovered = list(BagReader(bag))
    assert 0 < len(recovered) == report["message_count"] < 2362
    assert set(m.data for m in recovered) <= set(m.data for m in BagReader(SAMPLE_BAG))


def test_nothing_salvageable_is_an_error_and_the_bag_is_untouched(tmp_path):
    bag, path = _sample_copy(tmp_path)
    import pytest
    from rollability_ros.core.bags.metadata import BagError

    path.write_bytes(bytes(range(256)) * 400)
    before = {p.name: p.read_bytes() for p in bag.iterdir()}
    with pytest.raises(BagError, match="nothing can be saved"):
        recover(bag)
    assert {p.name: p.read_bytes() for p in bag.iterdir()} == before


def test_bag_recover_cli_exits_non_zero_when_nothing_can_be_saved(tmp_path):
    bag, path = _sample_copy(tmp_path)
    path.write_bytes(b"\x00" * 5000)
    result = subprocess.run([sys.executable, "-m", "rollability_ros.cli", "bag", "recover", str(bag)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode != 0 and "nothing can be saved" in result.stderr
    assert path.read_bytes() == b"\x00" * 5000


def _killed_writer_bag(tmp_path):
    """A bag whose writer acknowledged 400 messages, buffered 50 more and was SIGKILLed."""
    bag = tmp_path / "killed"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([os.path.dirname(__file__), os.environ.get("PYTHONPATH", "")]))
    process = subprocess.Popen([sys.executable, "-c", WRITER_SCRIPT, str(bag)], stdout=subprocess.PIPE, text=True,
                               env=env)
    try:
        assert process.stdout.readline().strip() == "acknowledged 400"
        assert process.stdout.readline().strip() == "unflushed 50"
    finally:
        process.send_signal(signal.SIGKILL)
        process.wait(timeout=30)
    assert process.returncode == -signal.SIGKILL
    return bag


def test_a_restarted_writer_continues_the_bag_left_open(tmp_path):
    """Was: "output_dir ... exists and is not an empty directory", so a restarted recorder never recorded again."""
    from rollability_ros.core.bags.recover import recording_gaps
    from rollability_ros.core.bags.writer import BagWriter
    from test_bags import T0_NS

    bag = _killed_writer_bag(tmp_path)
    files_before = len(list(bag.glob("*.mcap")))
    with BagWriter(bag, continue_open=True, custom_data={"operator": "kill test"}) as writer:
        assert writer.continued["message_count"] == 400
        writer.add_topic("/a", "std_msgs/msg/String")
        for index in range(1000, 1010):
            writer.write("/a", string_cdr(f"message {index}"), T0_NS + index)
    messages = [m.data for m in BagReader(bag)]
    assert messages == [string_cdr(f"message {i}") for i in [*range(400), *range(1000, 1010)]]
    information = read_metadata(bag)
    assert len(information["relative_file_paths"]) == files_before + 1 == len(list(bag.glob("*.mcap")))
    assert information["custom_data"]["operator"] == "kill test"
    topics = {t["topic_metadata"]["name"]: t["message_count"] for t in information["topics_with_message_count"]}
    assert topics == {"/a": 410, "/quiet": 0}
    assert recording_gaps(bag) == [(T0_NS + 399, T0_NS + 1000)]
    assert bag_info(bag)["warnings"] == []

    # issue 26: the study names every topic's own missed window, not only the outcomes'
    from rollability_ros.core.bags.recover import missed_windows
    from rollability_ros.core.graph.study import compare_bags_with_store

    ((topic, window),) = missed_windows(bag)[0].items()
    assert topic == "/a" and (window["after_ns"], window["until_ns"]) == (T0_NS + 399, T0_NS + 1000)
    assert window["rate_hz"] == pytest.approx(409 / (1009 / 1e9))
    _, note = compare_bags_with_store(set(), [], recording_gaps(bag), missed_windows(bag))
    assert "restarted 1 time(s)" in note and "every topic's missed window" in note
    assert "/a 22:13:20.000 to 22:13:20.000 UTC (0.0 s, about 243 messages at its" in note   # 601 ns at 409 per 1009 ns


def test_a_restarted_writer_does_not_record_again_what_the_bag_holds(tmp_path):
    """Issue 26: a transient-local publisher re-delivers its history to a restarted recorder (442 outcomes for 400
    trials). Copies of held messages (same topic, send time and bytes) are skipped and counted; a message the
    killed writer never flushed, re-delivered with its original send time, fills the gap; new ones are recorded."""
    from rollability_ros.core.bags.writer import DUPLICATES_KEY, BagWriter
    from test_bags import T0_NS

    bag = _killed_writer_bag(tmp_path)        # /a (transient-local): 400 flushed, 50 lost in the open chunk
    with BagWriter(bag, continue_open=True) as writer:
        writer.add_topic("/a", "std_msgs/msg/String")
        restart_ns = T0_NS + 10_000
        for index in range(450):              # the publisher's history, re-delivered with its send times
            written = writer.write("/a", string_cdr(f"message {index}"), restart_ns + index, T0_NS + index)
            assert written == (index >= 400)
        for index in range(1000, 1010):       # published after the restart
            assert writer.write("/a", string_cdr(f"message {index}"), restart_ns + index, restart_ns + index)
        assert writer.duplicates_skipped == {"/a": 400}
    messages = [m.data for m in BagReader(bag)]
    assert messages == [string_cdr(f"message {i}") for i in [*range(450), *range(1000, 1010)]]
    assert len(set(messages)) == len(messages) == 460
    information = read_metadata(bag)
    assert information["message_count"] == 460 and information["custom_data"][DUPLICATES_KEY] == "400"
    info = bag_info(bag)
    assert info["message_count"] == 460 and info["warnings"] == []


def test_a_closed_bag_is_not_continued(tmp_path):
    import pytest
    from rollability_ros.core.bags.writer import BagWriter

    bag = tmp_path / "closed"
    write_string_bag(bag, 10)
    with pytest.raises(ValueError, match="closed bag"):
        BagWriter(bag, continue_open=True)


def test_stored_outcomes_missing_from_the_bag_are_accepted_only_inside_a_reported_gap():
    from rollability_ros.core.graph.study import compare_bags_with_store
    from rollability_ros.core.records import LaunchCondition, LaunchOutcome

    def outcome(index, stamp_s):
        return LaunchOutcome(run_id="s", trial_id=f"t{index}", condition=LaunchCondition("A", 1.3, 1.5, 0.0, index),
                             backend="sim", upright=True, stamp_s=stamp_s)

    stored = [outcome(0, 100.0), outcome(1, 105.0), outcome(2, 110.0), outcome(3, 120.0)]
    gap = (int(104e9), int(111e9))
    problem, note = compare_bags_with_store({"t0", "t3"}, stored, [gap])
    assert problem == "" and "restarted 1 time" in note and "(2 stored outcome(s) not in a bag)" in note
    problem, _ = compare_bags_with_store({"t0", "t1", "t2"}, stored, [gap])
    assert "1 stored outcome(s) missing from the bags outside any reported gap (e.g. t3)" in problem
    problem, note = compare_bags_with_store({"t0", "t1", "t2"}, stored, [])
    assert problem and note == ""
    assert compare_bags_with_store({"t0", "t1", "t2", "t3"}, stored, []) == ("", "")


# --- issue 26: nothing saved means nothing changed; every rewritten file keeps a backup; info checks the CRCs --------
def _header_only(path):
    """The first bytes of the sample up to the end of its header record: magic + header, nothing else."""
    data = path.read_bytes()
    length = int.from_bytes(data[9:17], "little")
    return data[:8 + 9 + length]


def _first_chunk_cut(path):
    """The sample cut in the middle of its first chunk: the schemas and channels before it, no complete chunk."""
    first = _chunk_indexes(path)[0]
    return path.read_bytes()[:first.chunk_start_offset + first.chunk_length // 2]


def _every_chunk_flipped(path):
    data = bytearray(path.read_bytes())
    for chunk in _chunk_indexes(path):
        middle = chunk.chunk_start_offset + chunk.chunk_length // 2
        for offset in range(middle, middle + 64):
            data[offset] ^= 0xFF
    return bytes(data)


@pytest.mark.parametrize("damage", [
    lambda path: b"",                          # empty
    lambda path: path.read_bytes()[:10],       # tiny: 10 bytes, the magic and two more
    _header_only,                              # magic and header record only
    _first_chunk_cut,                          # truncated inside the first chunk
    _every_chunk_flipped,                      # 64 bytes flipped in every chunk: no CRC matches
], ids=["empty", "10-byte", "header-only", "truncated", "bit-flipped"])
def test_recover_refuses_a_bag_from_which_nothing_can_be_saved_and_changes_no_file(tmp_path, damage):
    """Was: exit 0, "metadata.yaml rewritten, 0 messages", the 2362 messages metadata.yaml declared overwritten."""
    from doubles import tree_checksums

    bag, path = _sample_copy(tmp_path)
    path.write_bytes(damage(path))
    before = tree_checksums(bag)
    result = subprocess.run([sys.executable, "-m", "rollability_ros.cli", "bag", "recover", str(bag)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2, result.stdout + result.stderr
    assert "nothing can be saved" in result.stderr and len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert tree_checksums(bag) == before


def test_every_file_recover_rewrites_keeps_a_numbered_backup(tmp_path):
    """The damaged storage file, metadata.yaml and the open writer's sidecar are kept; a second recovery of the
    same bag adds -2 backups instead of overwriting the first ones."""
    from rollability_ros.core.bags.recover import BACKUP_SUFFIX

    bag = _killed_writer_bag(tmp_path)
    originals = {p.name: p.read_bytes() for p in bag.iterdir()}
    report = recover(bag)
    assert report["message_count"] == 400 and report["metadata_rewritten"]
    assert report["metadata_backup"] == "metadata.yaml" + BACKUP_SUFFIX
    assert (bag / report["metadata_backup"]).read_bytes() == originals["metadata.yaml"]
    assert (bag / report["sidecar_backup"]).read_bytes() == originals[".recovery.json"]
    for entry in report["files"]:
        if entry["status"] == "recovered":
            assert (bag / entry["backup"]).read_bytes() == originals[entry["path"]]
    recovered_metadata = (bag / "metadata.yaml").read_bytes()

    last = sorted(p for p in bag.glob("*.mcap"))[-1]
    first_backup = bag / (last.name + BACKUP_SUFFIX)
    assert first_backup.exists()                     # the killed writer's open file was the one recovered
    kept = first_backup.read_bytes()
    last.write_bytes(last.read_bytes()[:-40])       # damaged again (its footer cut)
    again = recover(bag)
    (entry,) = [e for e in again["files"] if e["status"] == "recovered"]
    assert entry["backup"] == last.name + BACKUP_SUFFIX + "-2" and first_backup.read_bytes() == kept
    assert (bag / ("metadata.yaml" + BACKUP_SUFFIX)).read_bytes() == originals["metadata.yaml"]  # first kept
    if again["metadata_rewritten"]:
        assert (bag / again["metadata_backup"]).read_bytes() == recovered_metadata
    assert [m.data for m in BagReader(bag)] == [string_cdr(f"message {i}") for i in range(400)]


def _bag_info_cli(*argv):
    return subprocess.run([sys.executable, "-m", "rollability_ros.cli", "bag", "info", *argv],
                          capture_output=True, text=True, timeout=120)


def test_bag_info_checks_every_chunk_crc_and_names_corrupt_chunks(tmp_path):
    """Was: `bag info` on a bag with 64 corrupt bytes in a chunk exited 0 without noticing."""
    bag, path = _sample_copy(tmp_path)
    chunks = _chunk_indexes(path)
    clean = _bag_info_cli(str(bag))
    assert clean.returncode == 0 and f"Chunk CRCs:        verified: all {len(chunks)} chunks match" in clean.stdout

    middle = chunks[1].chunk_start_offset + chunks[1].chunk_length // 2
    _flip(path, range(middle, middle + 64))
    damaged = _bag_info_cli(str(bag))
    assert damaged.returncode == 1, damaged.stdout + damaged.stderr
    assert f"1 of {len(chunks)} chunks fail their check" in damaged.stderr
    assert f"corrupt: bag_0.mcap: the chunk at byte {chunks[1].chunk_start_offset} is corrupt" in damaged.stdout
    assert "Traceback" not in damaged.stderr and len(damaged.stderr.strip().splitlines()) == 1
    assert "Messages:          2362" in damaged.stdout      # the summary is still shown

    unchecked = _bag_info_cli(str(bag), "--no-verify")
    assert unchecked.returncode == 0 and "Chunk CRCs:        not verified" in unchecked.stdout
    single_file = _bag_info_cli(str(path), "--json")
    assert single_file.returncode == 1 and '"corrupt_chunks": [' in single_file.stdout


def test_the_gap_note_estimates_steady_topics_only_and_counts_stored_outcomes_in_the_window():
    """Issue 42: for an event topic the note says what is known ("nothing published" when the store holds no
    outcome of that window that the bag lacks), never an estimate from its mean rate."""
    from rollability_ros.core.graph.study import compare_bags_with_store

    start = 1_700_000_000 * 10**9
    window = {"/rollability/launch_outcomes": {"after_ns": start, "until_ns": start + 4 * 10**9, "rate_hz": 2.0,
                                               "periodic": True},
              "/rollability/rig/pose": {"after_ns": start, "until_ns": start + 4 * 10**9, "rate_hz": 100.0,
                                        "periodic": True},
              "/rollability/summary": {"after_ns": start, "until_ns": start + 4 * 10**9, "rate_hz": 2.0,
                                       "periodic": False}}
    gaps = [(start, start + 4 * 10**9)]
    _, note = compare_bags_with_store(set(), [], gaps, [window])
    assert "/rollability/launch_outcomes" in note and "(4.0 s, nothing published)" in note
    assert "/rollability/rig/pose 22:13:20.000 to 22:13:24.000 UTC (4.0 s, about 399 messages at its 100 Hz)" in note
    assert "/rollability/summary 22:13:20.000 to 22:13:24.000 UTC (4.0 s, an event topic: what it published then " \
           "is not known)" in note
    from rollability_ros.core.records import LaunchCondition, LaunchOutcome

    lost = LaunchOutcome(run_id="s", trial_id="t1", condition=LaunchCondition("A", 1.3, 1.5, 0.0, 1), backend="sim",
                         upright=True, stamp_s=(start + 2 * 10**9) / 1e9)
    problem, note = compare_bags_with_store(set(), [lost], gaps, [window])
    assert not problem and "(4.0 s, 1 message(s) published then, in the store, not in the bag)" in note


def _topics_edit(replacement):
    def edit(text):
        head, tail = text.split("  topics_with_message_count:\n", 1)
        return head + "  topics_with_message_count:\n" + replacement + tail
    return edit


@pytest.mark.parametrize("edit, reason", [
    (_topics_edit("  - 5\n"), r"topics_with_message_count\[0\] must be a mapping"),
    (_topics_edit("  - message_count: 3\n"), r"topics_with_message_count\[0\] must be a mapping"),
    (lambda text: text.replace("message_count: 100", "message_count: many", 1), "message_count must be a whole"),
    (lambda text: text.replace("- bag_0.mcap", "- 7"), "relative_file_paths must be a list of file names"),
    (lambda text: text.replace("depth: 5", "depth: 5\n        colour: red", 1), "unknown QoS profile keys"),
    (lambda text: b"\xff\xfe" + text.encode(), "not UTF-8 text"),
], ids=["entry-int", "entry-no-metadata", "count-text", "file-int", "qos-key", "binary"])
def test_a_damaged_metadata_yaml_is_named_by_every_reader_and_recover_rewrites_it(tmp_path, edit, reason):
    """Was: a topic entry that is not a mapping, or lacks topic_metadata or its name, raised TypeError / KeyError
    (a traceback) in `bag info`, `report`, `play` and `bag recover`; bytes that are not UTF-8 gave "'utf-8' codec
    can't decode" naming no file, and recover refused both. Now each reader names the file and the field, and
    recover rewrites metadata.yaml from the storage files, keeping the damaged one as a backup."""
    bag = tmp_path / "bag"
    write_string_bag(bag, 200)
    metadata = bag / "metadata.yaml"
    text = metadata.read_text()
    assert "message_count: 100" in text and "- bag_0.mcap" in text and "depth: 5" in text
    damaged = edit(text)
    metadata.write_bytes(damaged if isinstance(damaged, bytes) else damaged.encode())
    before = metadata.read_bytes()
    for read in (bag_info, BagReader, read_metadata):
        with pytest.raises(BagError, match=reason) as caught:
            read(str(bag))
        assert "metadata.yaml" in str(caught.value)
    report = recover(str(bag))
    assert report["message_count"] == 200 and report["metadata_backup"] == "metadata.yaml.before-recover"
    assert (bag / "metadata.yaml.before-recover").read_bytes() == before
    assert len(list(BagReader(str(bag)))) == 200 and bag_info(str(bag))["message_count"] == 200


def test_recover_leaves_alone_mcap_files_that_are_not_the_bags_splits(tmp_path):
    """Was: every *.mcap in the folder was taken as a split: a copy of a split (`copy_of_bag.mcap`) was adopted and
    every message counted twice, and a stray `notes.mcap` that is no MCAP made recovery refuse the whole bag. Now
    only the files metadata.yaml lists and unlisted splits of the same series are the bag's."""
    bag = tmp_path / "bag"
    write_string_bag(bag, 200, split_max_duration_s=0.5)
    splits = sorted(path.name for path in bag.glob("*.mcap"))
    assert len(splits) >= 2
    (bag / "copy_of_bag.mcap").write_bytes((bag / splits[0]).read_bytes())
    (bag / "notes.mcap").write_text("the operator's notes\n")
    last = bag / splits[-1]
    last.write_bytes(last.read_bytes()[:-200])          # a killed writer's last split
    metadata = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    metadata["relative_file_paths"] = splits[:-1]        # ... not listed yet
    (bag / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": metadata}))
    strays = {name: (bag / name).read_bytes() for name in ("copy_of_bag.mcap", "notes.mcap")}
    report = recover(str(bag))
    assert [f["path"] for f in report["files"]] == splits
    assert read_metadata(str(bag))["relative_file_paths"] == splits
    assert 150 <= report["message_count"] <= 200   # not 200 + the copy's
    assert len(list(BagReader(str(bag)))) == report["message_count"]
    assert {name: (bag / name).read_bytes() for name in strays} == strays
