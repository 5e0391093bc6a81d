"""The AIS feed: NMEA AIS sources (UDP listeners, TCP clients) decoded into the latest report of each Aid to
Navigation (gcs.ais.feed.AisFeed; the decoding is uavcore.ais and uavcore.ais_stream, the table gcs.domain.aton_table).
"""
