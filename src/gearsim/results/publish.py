"""Publishing a built catalogue atomically, and setting a damaged one aside for a rebuild."""

from __future__ import annotations

import os
from pathlib import Path

from gearsim.errors import CatalogueError, one_line
from gearsim.results.parquet import _prepare_dir, _tmp_name, now_iso
from gearsim.results.schema import REBUILD, catalogue_problem, open_catalogue


def publish(built: str | Path, target: str | Path) -> Path:
    """Make ``target`` the catalogue ``built``, atomically: a hard link (or copy) of ``built`` under
    a temporary name in ``target``'s directory, renamed over ``target``.

    At every instant ``target`` is either the previous catalogue or the new one, whole. Readers
    holding the previous file open keep reading it (the rename does not change its inode), and a
    workflow that deletes ``built`` before rebuilding it leaves ``target`` untouched.
    """
    import shutil

    built, target = Path(built), Path(target)
    open_catalogue(built).close()  # never publish a file that readers would refuse
    _prepare_dir(target, need=0)  # a hard link needs no room (a copy: checked as it goes)
    tmp = _tmp_name(target)
    try:
        if tmp.exists():
            tmp.unlink()
        try:
            os.link(built, tmp)
        except OSError:  # no hard links here (another file system, FAT, ...): copy
            shutil.copyfile(built, tmp)
        os.replace(tmp, target)
    except OSError as exc:
        raise CatalogueError(
            f"cannot publish {built} as {target} ({one_line(exc)}); {target} is unchanged"
        ) from None
    finally:
        if tmp.exists():
            tmp.unlink()
    return target


def publish_anywhere(built: str | Path, target: str, study: str | None = None) -> str:
    """Publish ``built`` to ``target``: a file (:func:`publish`), or a database URL as the study
    ``study`` (:func:`gearsim.results.server_publish.publish_study`). Returns where, for a line
    (a URL's password hidden)."""
    from gearsim.results.server import is_server_url, safe_url

    if not is_server_url(target):
        if study is not None:
            raise CatalogueError(f"--study {study}: a study is published to a database URL "
                                 f"(--to postgresql://...), not to the file {target}")
        return str(publish(built, target))
    if study is None:
        raise CatalogueError(f"--to {safe_url(target)}: name the study to publish (--study NAME)")
    from gearsim.results.server_publish import publish_study

    counts = publish_study(built, target, study)
    return f"{safe_url(target)} study {study} ({counts.get('cells', 0)} cells)"


def migrate_anywhere(paths: list[str], study: str | None = None
                     ) -> list[tuple[str, tuple[int, int]]]:
    """Migrate catalogue files, or the study ``study`` of one database URL; ``[(where, (old,
    new))]``."""
    from gearsim.results.schema import migrate_catalogue
    from gearsim.results.server import is_server_url, safe_url

    urls = [p for p in paths if is_server_url(p)]
    if not urls:
        if study is not None:
            raise CatalogueError(f"--study {study}: a study is migrated on a database URL")
        return [(p, migrate_catalogue(p)) for p in paths]
    if len(paths) != 1 or study is None:
        raise CatalogueError(f"{safe_url(urls[0])}: migrate one database's study at a time "
                             "(gearsim catalogue migrate URL --study NAME)")
    from gearsim.results.server_read import migrate_study

    return [(f"{safe_url(urls[0])} study {study}", migrate_study(urls[0], study))]


def set_aside_damaged(published: str | Path, built: str | Path, *,
                      dry_run: bool = False) -> list[str]:
    """Make the workflow rebuild a catalogue that readers would refuse. Returns a line for each.

    ``published`` is what readers open (``results/catalogue.sqlite``), ``built`` the catalogue
    rule's output it is published from. When either is damaged, foreign or of another schema
    version (:func:`catalogue_problem`), ``built`` is moved into ``damaged/`` beside it (kept
    for inspection, never deleted): its rule then rebuilds it from the verified Parquet files
    and publishes it over ``published``. ``dry_run``: only say so.
    """
    published, built = Path(published), Path(built)
    lines, seen = [], []
    for p in (published, built):
        if not p.exists() or any(os.path.samefile(p, q) for q in seen):
            continue  # the built file is mostly the published one (a hard link)
        seen.append(p)
        why = catalogue_problem(p)
        if why:
            for tail, keep in ((f"; {REBUILD})", ")"), (f", or {REBUILD})", ")"),
                               (f" ({REBUILD})", "")):
                why = why.replace(tail, keep)
            lines.append(why)
    if not lines:
        return []
    what = "the next run rebuilds it" if dry_run else "rebuilding it from the Parquet files"
    lines = [f"{line}: {what}" for line in lines]
    if not dry_run and built.exists():
        stamp = now_iso().replace(":", "")
        aside = built.parent / "damaged" / f"{built.stem}-{stamp}.sqlite"
        k = 0
        while aside.exists():
            k += 1
            aside = built.parent / "damaged" / f"{built.stem}-{stamp}-{k}.sqlite"
        try:
            aside.parent.mkdir(parents=True, exist_ok=True)
            os.replace(built, aside)
        except OSError as exc:
            raise CatalogueError(f"cannot move {built} aside ({one_line(exc)})") from None
        lines.append(f"{built} kept as {aside}")
    return lines


