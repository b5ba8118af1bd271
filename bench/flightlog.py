"""Benchmark of the MCAP flight log: write 10^6 samples of a channel (best and median of 3),
read them back with the fast path, and compare with the mcap packages' own way (mcap_ros2's
Writer.write_message, iter_decoded_messages) on the same data.

    python bench/flightlog.py [--samples 1000000] [--json out.json]

The data are a simulated MIMU raw channel (realistic compressibility): the shipped
high-dynamic flight, looped. mcap_ros2's writer (a message dict a sample, zstd chunks of
1 MiB) and iter_decoded_messages are timed on the first 100 000 messages and scaled (both
are linear). zstd alone - the log's own chunks compressed at the writer's
level and decompressed, on 2 threads, with nothing else to do - is the ceiling of both
the writer (which also encodes the messages, on the same 2 cores) and the reader.
"""
import argparse
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
import zstandard                                        # noqa: E402
from mcap.reader import make_reader                     # noqa: E402
from mcap.records import Chunk                          # noqa: E402
from mcap.stream_reader import StreamReader             # noqa: E402
from mcap_ros2.decoder import DecoderFactory            # noqa: E402
from mcap_ros2.writer import Writer as Ros2Writer       # noqa: E402

from publish import publish  # noqa: E402
from mimunav.motion import truth                               # noqa: E402
from mimunav.flightlog import FlightLog, LogWriter      # noqa: E402
from mimunav.flightlog import schemas as S              # noqa: E402
from mimunav.flightlog.writer import ZSTD_PARAMETERS    # noqa: E402
from mimunav.motion.profile import Profile                     # noqa: E402
from mimunav.sensors.mimu import MimuUnit                    # noqa: E402


def zstd_alone(path, repeats=3):
    """(compress s, decompress s, bytes of records), best of `repeats`: the log's chunks,
    uncompressed, compressed again with the writer's parameters on 2 threads (as the writer does)
    and decompressed on 2 threads (as the reader does)."""
    from concurrent.futures import ThreadPoolExecutor
    with open(path, "rb") as fh:
        chunks = [r for r in StreamReader(fh, emit_chunks=True).records if isinstance(r, Chunk)]
    raw = [zstandard.ZstdDecompressor().decompress(c.data, max_output_size=c.uncompressed_size)
           for c in chunks]
    packed = [c.data for c in chunks]
    compressor = zstandard.ZstdCompressor(
        compression_params=zstandard.ZstdCompressionParameters(**ZSTD_PARAMETERS))

    def unpack(part):
        """Each chunk decompressed and let go, as the reader does (it holds DECODE_AHEAD
        chunks): holding all 163 MB would time the kernel's page faults, not zstd."""
        d = zstandard.ZstdDecompressor()
        for c, r in part:
            d.decompress(c, max_output_size=len(r))

    pairs = list(zip(packed, raw))
    times = {"compress": [], "decompress": []}
    with ThreadPoolExecutor(2) as pool:
        for _ in range(repeats):
            t0 = time.perf_counter()
            compressor.multi_compress_to_buffer(raw, threads=2)
            times["compress"].append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            list(pool.map(unpack, (pairs[0::2], pairs[1::2])))
            times["decompress"].append(time.perf_counter() - t0)
    return min(times["compress"]), min(times["decompress"]), sum(len(r) for r in raw)


def peer_write_s(path, stamps, raw, m):
    """Seconds of mcap_ros2's Writer for the first m samples, one write_message each."""
    with open(path, "wb") as fh:
        writer = Ros2Writer(fh)
        schema = writer.register_msgdef(S.RAW_MIMU, S.SCHEMAS[S.RAW_MIMU].decode())
        t0 = time.perf_counter()
        for k in range(m):
            stamp = int(stamps[k])
            writer.write_message("/mimu/raw", schema, {
                "header": {"stamp": {"sec": stamp // 10**9, "nanosec": stamp % 10**9},
                           "frame_id": "mimu"},
                "sample_index": int(raw["sample_index"][k]),
                **{key: raw[key][k].tolist() for key in
                   ("gyro_volts", "accel_volts", "accel_temperature", "gyro_frequency")}},
                log_time=stamp, publish_time=stamp)
        writer.finish()
        return time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=1_000_000)
    ap.add_argument("--json")
    args = ap.parse_args()
    n = args.samples
    prof = Profile.load(ROOT / "flights" / "high-dynamic.toml")
    doc = {"name": "bench", "start": {"latitude_deg": 40, "longitude_deg": 100, "height_m": 3000,
                                      "speed_m_s": 250, "heading_deg": 30, "ramp_s": 0.2},
           "segment": prof.segments * int(np.ceil(n / 1000 / prof.duration))}
    t = np.arange(0, n + 1) / 1000.0
    run = truth.generate(Profile.from_dict(doc).motion(), t)
    raw = MimuUnit.draw(1).simulate(t[1:], run.dtheta, run.dv, np.full(n, 15.0),
                                    np.random.default_rng(0))
    stamps = 1_767_225_600 * 10**9 + np.round(t[1:] * 1e9).astype(np.int64)
    with tempfile.TemporaryDirectory() as tmp:
        writes = []
        for k in range(3):
            path = os.path.join(tmp, f"bench{k}.mcap")
            t0 = time.perf_counter()
            with LogWriter(path) as log:
                log.write("/mimu/raw", S.RAW_MIMU, "mimu", stamps,
                          sample_index=raw["sample_index"], gyro_volts=raw["gyro_volts"],
                          accel_volts=raw["accel_volts"],
                          accel_temperature=raw["accel_temperature"],
                          gyro_frequency=raw["gyro_frequency"])
            writes.append(time.perf_counter() - t0)
        t_write = min(writes)
        size = os.path.getsize(path)
        reads = []
        for _ in range(3):
            with FlightLog(path) as lg:
                t0 = time.perf_counter()
                msgs = lg.read("/mimu/raw")
                reads.append(time.perf_counter() - t0)
        assert np.array_equal(msgs["gyro_volts"], raw["gyro_volts"])
        t_pack, t_unpack, records = zstd_alone(path)
        m = min(n, 100_000)
        t_peer_write = peer_write_s(os.path.join(tmp, "peer.mcap"), stamps, raw, m) * n / m
        with open(path, "rb") as fh:
            reader = make_reader(fh, decoder_factories=[DecoderFactory()])
            t0 = time.perf_counter()
            for k, _ in enumerate(reader.iter_decoded_messages()):
                if k + 1 == m:
                    break
            t_generic = (time.perf_counter() - t0) * n / m
    res = {"machine": f"{platform.machine()} {os.cpu_count()} cores, {platform.python_version()}",
           "samples": n, "file_mb": size / 1e6, "write_s": t_write, "writes_s": writes,
           "mcap_ros2_write_s": t_peer_write,
           "read_s_first": reads[0], "read_s_best": min(reads),
           "read_samples_per_s_first": n / reads[0], "read_samples_per_s_best": n / min(reads),
           "iter_decoded_messages_s": t_generic, "speedup_first": t_generic / reads[0],
           "zstd_compress_s": t_pack, "zstd_decompress_s": t_unpack}
    publish(__file__, [
        (f"log write, {n:.0e} /mimu/raw samples", f"{t_write:.2f} s, {n / t_write / 1e6:.2f} M "
         f"msg/s best, {n / sorted(writes)[1] / 1e6:.2f} M median of 3 ({size / 1e6:.1f} MB); "
         f"{t_peer_write / t_write:.0f}x mcap_ros2's Writer.write_message"),
        (f"log read, {n:.0e} /mimu/raw samples", f"{n / reads[0] / 1e6:.1f} M samples/s first, "
         f"{n / min(reads) / 1e6:.1f} M best of 3; {res['speedup_first']:.0f}x the mcap "
         "package's iter_decoded_messages (chunks decompressed on 2 threads)"),
        ("zstd alone on that log's chunks (the writer's parameters, 2 threads): the writer's "
         "and the reader's ceiling", f"compress {n / t_pack / 1e6:.2f} M msg/s, decompress "
         f"{n / t_unpack / 1e6:.2f} M msg/s ({records / 1e6:.0f} MB of records)")],
        res, args.json)


if __name__ == "__main__":
    main()
