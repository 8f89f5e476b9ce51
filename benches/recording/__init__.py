"""The run recording: the ONE package that knows the HDF5 layout (``benches/RECORDING.md``).

Parts: :mod:`.layout` (format constants, dtypes, typed records, errors), :mod:`.encoding` (counts, checksums,
the chunk encoder, which checks every chunk as it writes it), :mod:`.writer` (:class:`Hdf5Recorder`), :mod:`.reader`
(:func:`open_recording`), :mod:`.written` (what the recorder verified while writing, for the same process's
identification), :mod:`.salvage` (damaged recordings, decoded samples). Import from the package:
``from benches.recording import open_recording``.

Writing (:class:`Hdf5Recorder`): one file per run, written incrementally. Samples are buffered in memory and
written in short bursts at checkpoints (every step boundary and every ``checkpoint_samples`` samples), each
burst followed by a flush, so a process killed at any moment (even by SIGKILL) leaves a readable file holding
every completed step. Every dataset is chunked with HDF5's Fletcher-32 checksum filter (and shuffle + gzip
level 1 compression); every file-format structure carries HDF5's own metadata checksum (1.8 object headers,
superblock v2); when a step closes, a SHA-256 over that step's sample rows and table readings is stored in its
step row. Accelerometer and gyro samples that are quantised counts (``quanta``) are stored as int32 counts and
an exact float64 residual, so the stored values equal the recorded ones bit for bit.

Reading (:func:`open_recording` → :class:`Recording`): a typed run header (:class:`RunHeader`), typed steps
(:class:`StepRecord`), samples (:class:`Samples`, whole or as an iterator of chunks), table readings
(:class:`TableReadings`), events (:class:`Event`) and the simulator's truth (:class:`Truth`). On opening,
every checksum is verified (in the process that has just written the file, ``open_recording(path,
written=True)`` uses the verification done while writing instead of a second pass: ``benches/RECORDING.md``, "Where
the integrity is verified"); any failure, and any HDF5 error (also while reading data lazily), raises
:class:`RecordingError` naming the file, the dataset and the step. A recording written by another tool to
the layout without checksums (format version 1) stays usable: :attr:`Recording.integrity_verified` is False
and :attr:`Recording.integrity_note` says so in one line.

No module outside this package imports h5py or names a dataset path.
"""

from .encoding import _encode_chunk, _fletcher32
from .layout import (
    AUX_NAME,
    FORMAT,
    FORMAT_VERSION,
    READABLE_VERSIONS,
    RECORDING_NAME,
    STATUS_VALUES,
    AuxReadings,
    Event,
    RecordingDamaged,
    RecordingError,
    RunHeader,
    Samples,
    StepRecord,
    TableReadings,
    TimeSources,
    Truth,
    recording_file,
)
from .reader import Recording, open_recording
from .salvage import salvage, write_decoded_samples
from .writer import Hdf5Recorder, Recorder, storage_filters
from .written import file_identity

__all__ = [
    "AUX_NAME",
    "AuxReadings",
    "TimeSources",
    "FORMAT",
    "FORMAT_VERSION",
    "READABLE_VERSIONS",
    "RECORDING_NAME",
    "STATUS_VALUES",
    "Event",
    "Hdf5Recorder",
    "Recorder",
    "Recording",
    "RecordingDamaged",
    "RecordingError",
    "RunHeader",
    "Samples",
    "StepRecord",
    "TableReadings",
    "Truth",
    "_encode_chunk",
    "_fletcher32",
    "file_identity",
    "open_recording",
    "recording_file",
    "salvage",
    "storage_filters",
    "write_decoded_samples",
]
