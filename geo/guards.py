"""Guards for files from outside, before any parser sees them: zip archives and XML prologs.

* Zip archives (`.kmz`, a Shapefile's `.zip`): a member is read only up to the size the archive
  declares for it (Python's zipfile stops there and checks the CRC), and the declared sizes are
  checked against a limit first, so a zip bomb is refused before a byte is inflated. GDAL's own
  /vsizip/ reads past a member's declared size, so archives are never handed to it: a Shapefile is
  extracted (bounded, basenames only, into a temporary folder) and GDAL reads the copy.
* XML (KML, GML): a DTD (`<!DOCTYPE`) is refused. Neither format needs one, and a DTD is how XML
  files attack a reader: external entities that read local files (XXE) and nested entities that
  expand without end (billion laughs). Python's expat refuses both already; GDAL's GML driver does
  not (it returned no features and no error for a billion-laughs file), so the check comes first.
"""

from __future__ import annotations

import re
import shutil
import zipfile
from pathlib import Path, PurePosixPath

from .errors import GeoError

MAX_MEMBER_BYTES = 1 << 30  # one KML document read into memory from a KMZ: 1 GiB declared at most
MAX_EXTRACT_BYTES = 4 << 30  # a Shapefile's members extracted from a zip: 4 GiB declared at most
_PROLOG_LIMIT = 1 << 20  # the XML prolog (before the root element) is looked at up to this many bytes
_ROOT_START = re.compile(r"<[A-Za-z_:]")
_COMMENT = re.compile(r"<!--.*?-->", re.S)


def _mib(size: int) -> str:
    return f"{size / (1 << 20):,.0f} MiB"


def open_zip(path: Path, what: str) -> zipfile.ZipFile:
    """The archive `path` (a `what`: "KMZ", "zip"), or GeoError for a file that is not one."""
    try:
        return zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError, ValueError, EOFError, NotImplementedError) as err:
        raise GeoError(f"{path}: cannot read the {what} archive ({str(err).splitlines()[0] if str(err) else type(err).__name__})") from None


def member_bytes(archive: zipfile.ZipFile, info: zipfile.ZipInfo, where: str) -> bytes:
    """One member's bytes, bounded by its declared size and MAX_MEMBER_BYTES."""
    if info.file_size > MAX_MEMBER_BYTES:
        raise GeoError(f"{where}: {info.filename} would inflate to {_mib(info.file_size)} (limit "
                       f"{_mib(MAX_MEMBER_BYTES)}): refused as a zip bomb or far too large")
    try:
        with archive.open(info) as member:
            return member.read(info.file_size + 1)  # zipfile never yields more than declared
    except (zipfile.BadZipFile, OSError, RuntimeError, ValueError, EOFError, NotImplementedError) as err:
        # a CRC or size that does not match (a damaged or forged archive), an encrypted member
        raise GeoError(f"{where}: cannot read {info.filename} from the archive "
                       f"({str(err).splitlines()[0] if str(err) else type(err).__name__})") from None


def extract(archive: zipfile.ZipFile, infos: list[zipfile.ZipInfo], folder: Path, where: str) -> list[Path]:
    """The members `infos` copied into `folder` under their base names, bounded (MAX_EXTRACT_BYTES
    declared in all, and no more than the free space there); the paths written."""
    total = sum(info.file_size for info in infos)
    if total > MAX_EXTRACT_BYTES:
        raise GeoError(f"{where}: its members would inflate to {_mib(total)} (limit {_mib(MAX_EXTRACT_BYTES)}): "
                       f"refused as a zip bomb or far too large")
    free = shutil.disk_usage(folder).free
    if total > free:
        raise GeoError(f"{where}: its members would inflate to {_mib(total)}, more than the {_mib(free)} free "
                       f"in {folder}")
    written = []
    for info in infos:
        target = folder / PurePosixPath(info.filename.replace("\\", "/")).name  # no path from the archive
        try:
            with archive.open(info) as member, open(target, "wb") as out:
                shutil.copyfileobj(member, out, 1 << 20)  # stops at the declared size, checks the CRC
        except (zipfile.BadZipFile, RuntimeError, ValueError, EOFError, NotImplementedError) as err:
            raise GeoError(f"{where}: cannot read {info.filename} from the archive "
                           f"({str(err).splitlines()[0] if str(err) else type(err).__name__})") from None
        except OSError as err:
            raise GeoError(f"{where}: cannot extract {info.filename} to {folder} ({err.strerror or err})") from None
        written.append(target)
    return written


def _decoded(head: bytes) -> str:
    """The head of an XML file as text, enough to find markup: UTF-16 by its byte-order mark or zero
    bytes, else byte for byte (UTF-8 and the other ASCII-compatible encodings keep '<!DOCTYPE' as is)."""
    if head.startswith((b"\xff\xfe", b"\xfe\xff")) or b"\x00" in head[:4]:
        big = head.startswith(b"\xfe\xff") or head[:1] == b"\x00"
        return head.decode("utf-16-be" if big else "utf-16-le", errors="replace")
    return head.decode("latin-1")


def refuse_dtd(head: bytes, where: str, fmt: str) -> None:
    """GeoError when the XML whose first bytes are `head` declares a DTD before its root element."""
    text = _COMMENT.sub("", _decoded(head[:_PROLOG_LIMIT]))
    root = _ROOT_START.search(text)
    prolog = text[:root.start()] if root else text
    if "<!DOCTYPE" in prolog or "<!ENTITY" in prolog:
        raise GeoError(f"{where}: the XML declares a DTD (<!DOCTYPE ...>); {fmt} needs none, and a DTD's entities "
                       f"can read local files or expand without end: refused")
    if root is None and len(head) >= _PROLOG_LIMIT:
        raise GeoError(f"{where}: no XML root element in its first {_mib(_PROLOG_LIMIT)}: not {fmt}")


def refuse_dtd_in_file(path: Path, where: str, fmt: str) -> None:
    """`refuse_dtd` on the first bytes of the file `path`."""
    try:
        with open(path, "rb") as f:
            head = f.read(_PROLOG_LIMIT)
    except OSError as err:
        raise GeoError(f"{where}: cannot read ({err.strerror or err})") from None
    refuse_dtd(head, where, fmt)
