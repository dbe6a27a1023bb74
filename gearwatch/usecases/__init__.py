"""The use-cases: what gearwatch does, each a plain function or small class over the repositories
(:mod:`storage`), the readers (:mod:`ingest`) and the pure rooms (:mod:`dsp`, :mod:`detection`,
:mod:`physics`). The doors (:mod:`gearwatch.cli`, :mod:`service`, :mod:`gearwatch.worker`) parse,
call one of these and present the answer; nothing here imports a door.

* :mod:`~gearwatch.usecases.analyze` — analyse one record (the per-record signal chain);
* :mod:`~gearwatch.usecases.ingest_file` — ingest one file (keep, analyse, store, evaluate alarms);
* :mod:`~gearwatch.usecases.alarms` — evaluate the alarm rules on a stored record;
* :mod:`~gearwatch.usecases.replay` — replay a whole campaign;
* :mod:`~gearwatch.usecases.watch` — ingest the files dropped into a folder;
* :mod:`~gearwatch.usecases.reconcile` — reconcile a record with the simulator (file or stored);
* :mod:`~gearwatch.usecases.job_queue` — the per-record and reconciliation jobs over RabbitMQ;
* :mod:`~gearwatch.usecases.keys` — create an API key;
* :mod:`~gearwatch.usecases.simulated_campaign` — write a simulated campaign.
"""
