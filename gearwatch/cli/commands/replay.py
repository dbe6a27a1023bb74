"""``gearwatch replay CAMPAIGN_DIR [--db URL] [--params FILE]``: ingest a whole campaign.

Every record of the manifest goes through the per-record job in the order the records were
taken (:func:`gearwatch.usecases.replay.replay_campaign`), with a progress bar on stderr and a
summary on stdout. Replaying again changes nothing; new parameters add result versions.
"""

from __future__ import annotations

import argparse
from typing import Any

from gearwatch.cli.shared import (
    add_common_arguments,
    database_url,
    manifest_path,
    parameters_from_args,
    raw_store_root,
)


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "replay",
        help="ingest a campaign record by record into the database",
        description=(
            "Ingest every record of a campaign (CAMPAIGN_DIR/campaign.toml) in the order they "
            "were taken: keep the raw file, analyse it, store per-tooth results and evaluate "
            "the alarm rules. Records already ingested with the same parameters are left "
            "alone; rejected records are stored with their reason."
        ),
    )
    parser.add_argument("campaign", metavar="CAMPAIGN_DIR",
                        help="campaign folder with campaign.toml (or the manifest itself)")
    parser.add_argument(
        "--reevaluate-alarms",
        action="store_true",
        help="afterwards, recompute the rig's alarms from the current results (after "
        "re-processing with new parameters; acknowledgements of the old alarms are lost)",
    )
    add_common_arguments(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from gearwatch.usecases.replay import replay_into_database

    manifest = manifest_path(args.campaign)
    params = parameters_from_args(args)
    summary = replay_into_database(
        manifest, database_url(args), raw_store_root(args), params,
        progress=not args.no_progress, reevaluate_alarms=args.reevaluate_alarms,
    )
    print("\n".join(summary.lines()))
    return 1 if summary.internal_errors else 0
