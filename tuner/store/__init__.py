"""The study storage as one room: Optuna's storages hardened for many processes and full disks
(:mod:`.storage` the ``StudyStore``, :mod:`.journal` the packed journal, :mod:`.rdb` the lean RDB
storage for PostgreSQL and SQLite, :mod:`.liveness` who is alive) and every use of Optuna's private
code (:mod:`.optuna_compat`, tested per touchpoint). Nothing is imported here: the modules load what
they need."""
